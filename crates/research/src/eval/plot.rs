//! Scatter plots of specimens (a morphospace: PC1–PC2, MDS coordinates),
//! coloured by a group label, as SVG (written by hand: axes, tick values,
//! legend, the specimen's name on hover) and as an RGB raster for PNG
//! (points, axes and legend swatches; no text).

use super::RgbImage;
use morphoid_data::present::escape;

/// What a scatter plot shows.
#[derive(Debug, Clone, PartialEq)]
pub struct Scatter {
    /// Title above the plot.
    pub title: String,
    /// Axis names.
    pub x_label: String,
    /// Axis names.
    pub y_label: String,
    /// One `(x, y)` per specimen.
    pub points: Vec<[f64; 2]>,
    /// Specimen names (SVG tooltips).
    pub names: Vec<String>,
    /// Each specimen's group (colour); `None`: grey.
    pub groups: Vec<Option<String>>,
}

/// Distinct colours for groups (Tableau 10 and two more), then repeated.
const PALETTE: [[u8; 3]; 12] = [
    [0x4e, 0x79, 0xa7],
    [0xf2, 0x8e, 0x2b],
    [0xe1, 0x57, 0x59],
    [0x76, 0xb7, 0xb2],
    [0x59, 0xa1, 0x4f],
    [0xed, 0xc9, 0x48],
    [0xb0, 0x7a, 0xa1],
    [0xff, 0x9d, 0xa7],
    [0x9c, 0x75, 0x5f],
    [0x2f, 0x2f, 0x2f],
    [0x1f, 0xbe, 0xcf],
    [0x8c, 0x56, 0x4b],
];
const UNGROUPED: [u8; 3] = [0xba, 0xb0, 0xac];

impl Scatter {
    /// The group names in sorted order, and each specimen's colour.
    pub fn colours(&self) -> (Vec<String>, Vec<[u8; 3]>) {
        let mut keys: Vec<String> = self.groups.iter().flatten().cloned().collect();
        keys.sort();
        keys.dedup();
        let colours = self
            .groups
            .iter()
            .map(|g| match g {
                Some(g) => keys
                    .binary_search(g)
                    .map_or(UNGROUPED, |k| PALETTE[k % PALETTE.len()]),
                None => UNGROUPED,
            })
            .collect();
        (keys, colours)
    }

    /// The data range, padded by 5 % (a unit range around a single value).
    fn range(&self) -> ([f64; 2], [f64; 2]) {
        let mut lo = [f64::INFINITY; 2];
        let mut hi = [f64::NEG_INFINITY; 2];
        for p in self
            .points
            .iter()
            .filter(|p| p.iter().all(|v| v.is_finite()))
        {
            for d in 0..2 {
                lo[d] = lo[d].min(p[d]);
                hi[d] = hi[d].max(p[d]);
            }
        }
        for d in 0..2 {
            if lo[d].partial_cmp(&hi[d]) != Some(std::cmp::Ordering::Less) {
                let c = if lo[d].is_finite() { lo[d] } else { 0.0 };
                (lo[d], hi[d]) = (c - 0.5, c + 0.5);
            }
            let pad = 0.05 * (hi[d] - lo[d]);
            lo[d] -= pad;
            hi[d] += pad;
        }
        (lo, hi)
    }
}

fn hex(c: [u8; 3]) -> String {
    format!("#{:02x}{:02x}{:02x}", c[0], c[1], c[2])
}

/// Plot area (left, top, width, height) of a canvas of `w × h`, leaving
/// room for a legend of `legend` entries on the right.
const SVG_SIZE: (f64, f64) = (760.0, 520.0);
const PLOT: (f64, f64, f64, f64) = (70.0, 40.0, 480.0, 420.0);

/// The plot as an SVG document.
pub fn scatter_svg(plot: &Scatter) -> String {
    let (lo, hi) = plot.range();
    let (left, top, w, h) = PLOT;
    let sx = |x: f64| left + (x - lo[0]) / (hi[0] - lo[0]) * w;
    let sy = |y: f64| top + h - (y - lo[1]) / (hi[1] - lo[1]) * h;
    let (keys, colours) = plot.colours();
    let mut s = format!(
        "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{}\" height=\"{}\" viewBox=\"0 0 {} {}\" font-family=\"sans-serif\" font-size=\"12\">\n<rect width=\"100%\" height=\"100%\" fill=\"white\"/>\n",
        SVG_SIZE.0, SVG_SIZE.1, SVG_SIZE.0, SVG_SIZE.1
    );
    s.push_str(&format!(
        "<text x=\"{}\" y=\"24\" text-anchor=\"middle\" font-size=\"15\">{}</text>\n",
        left + w / 2.0,
        escape(&plot.title)
    ));
    s.push_str(&format!(
        "<rect x=\"{left}\" y=\"{top}\" width=\"{w}\" height=\"{h}\" fill=\"none\" stroke=\"black\"/>\n"
    ));
    // Zero lines, when inside the range.
    if lo[0] < 0.0 && hi[0] > 0.0 {
        s.push_str(&format!(
            "<line x1=\"{0:.2}\" y1=\"{top}\" x2=\"{0:.2}\" y2=\"{1}\" stroke=\"#cccccc\"/>\n",
            sx(0.0),
            top + h
        ));
    }
    if lo[1] < 0.0 && hi[1] > 0.0 {
        s.push_str(&format!(
            "<line x1=\"{left}\" y1=\"{0:.2}\" x2=\"{1}\" y2=\"{0:.2}\" stroke=\"#cccccc\"/>\n",
            sy(0.0),
            left + w
        ));
    }
    for k in 0..=4 {
        let f = k as f64 / 4.0;
        let (x, y) = (lo[0] + f * (hi[0] - lo[0]), lo[1] + f * (hi[1] - lo[1]));
        s.push_str(&format!(
            "<text x=\"{:.2}\" y=\"{}\" text-anchor=\"middle\">{}</text>\n",
            sx(x),
            top + h + 16.0,
            tick(x)
        ));
        s.push_str(&format!(
            "<text x=\"{}\" y=\"{:.2}\" text-anchor=\"end\" dominant-baseline=\"middle\">{}</text>\n",
            left - 6.0,
            sy(y),
            tick(y)
        ));
    }
    s.push_str(&format!(
        "<text x=\"{}\" y=\"{}\" text-anchor=\"middle\">{}</text>\n",
        left + w / 2.0,
        top + h + 36.0,
        escape(&plot.x_label)
    ));
    s.push_str(&format!(
        "<text x=\"18\" y=\"{0}\" text-anchor=\"middle\" transform=\"rotate(-90 18 {0})\">{1}</text>\n",
        top + h / 2.0,
        escape(&plot.y_label)
    ));
    for (i, p) in plot.points.iter().enumerate() {
        if !p.iter().all(|v| v.is_finite()) {
            continue;
        }
        let name = plot.names.get(i).map_or("", String::as_str);
        s.push_str(&format!(
            "<circle cx=\"{:.2}\" cy=\"{:.2}\" r=\"4\" fill=\"{}\" stroke=\"black\" stroke-width=\"0.5\"><title>{}</title></circle>\n",
            sx(p[0]),
            sy(p[1]),
            hex(colours[i]),
            escape(name)
        ));
    }
    let lx = left + w + 20.0;
    for (k, key) in keys.iter().enumerate() {
        let y = top + 10.0 + 18.0 * k as f64;
        s.push_str(&format!(
            "<circle cx=\"{lx}\" cy=\"{y}\" r=\"5\" fill=\"{}\"/><text x=\"{}\" y=\"{y}\" dominant-baseline=\"middle\">{}</text>\n",
            hex(PALETTE[k % PALETTE.len()]),
            lx + 10.0,
            escape(key)
        ));
    }
    s.push_str("</svg>\n");
    s
}

/// A tick value with about three significant digits.
fn tick(v: f64) -> String {
    if v == 0.0 || !v.is_finite() {
        return "0".into();
    }
    let digits = (2 - v.abs().log10().floor() as i32).max(0) as usize;
    format!("{v:.digits$}")
}

/// The plot as an RGB raster of `width × height` (at least 64 × 64):
/// white background, frame, zero lines, a filled disc per specimen and a
/// column of legend swatches on the right (in the SVG's group order).
pub fn scatter_raster(plot: &Scatter, width: u32, height: u32) -> RgbImage {
    let (width, height) = (width.max(64), height.max(64));
    let mut img = RgbImage {
        width,
        height,
        pixels: vec![255; 3 * width as usize * height as usize],
    };
    let set = |img: &mut RgbImage, x: i64, y: i64, c: [u8; 3]| {
        if x >= 0 && y >= 0 && (x as u32) < img.width && (y as u32) < img.height {
            let k = 3 * (y as usize * img.width as usize + x as usize);
            img.pixels[k..k + 3].copy_from_slice(&c);
        }
    };
    let (lo, hi) = plot.range();
    let legend_w = (width / 6) as f64;
    let (left, top) = (0.08 * width as f64, 0.06 * height as f64);
    let (w, h) = (
        width as f64 - left - legend_w - 10.0,
        height as f64 - 2.0 * top,
    );
    let sx = |x: f64| left + (x - lo[0]) / (hi[0] - lo[0]) * w;
    let sy = |y: f64| top + h - (y - lo[1]) / (hi[1] - lo[1]) * h;
    let grey = [0xcc, 0xcc, 0xcc];
    if lo[0] < 0.0 && hi[0] > 0.0 {
        for y in top as i64..(top + h) as i64 {
            set(&mut img, sx(0.0) as i64, y, grey);
        }
    }
    if lo[1] < 0.0 && hi[1] > 0.0 {
        for x in left as i64..(left + w) as i64 {
            set(&mut img, x, sy(0.0) as i64, grey);
        }
    }
    for x in left as i64..=(left + w) as i64 {
        set(&mut img, x, top as i64, [0; 3]);
        set(&mut img, x, (top + h) as i64, [0; 3]);
    }
    for y in top as i64..=(top + h) as i64 {
        set(&mut img, left as i64, y, [0; 3]);
        set(&mut img, (left + w) as i64, y, [0; 3]);
    }
    let (keys, colours) = plot.colours();
    let r = ((width.min(height) as f64) / 120.0).max(2.0);
    let disc = |img: &mut RgbImage, cx: f64, cy: f64, c: [u8; 3]| {
        let ri = r.ceil() as i64 + 1;
        for dy in -ri..=ri {
            for dx in -ri..=ri {
                let d = ((dx * dx + dy * dy) as f64).sqrt();
                let colour = if d <= r - 1.0 {
                    c
                } else if d <= r {
                    [0; 3]
                } else {
                    continue;
                };
                set(img, cx as i64 + dx, cy as i64 + dy, colour);
            }
        }
    };
    for (p, &c) in plot.points.iter().zip(&colours) {
        if p.iter().all(|v| v.is_finite()) {
            disc(&mut img, sx(p[0]), sy(p[1]), c);
        }
    }
    for k in 0..keys.len() {
        let y = top + (k as f64 + 0.5) * 3.0 * r;
        disc(
            &mut img,
            width as f64 - legend_w + 2.0 * r,
            y,
            PALETTE[k % PALETTE.len()],
        );
    }
    img
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample() -> Scatter {
        Scatter {
            title: "PC1 & PC2".into(),
            x_label: "PC1 (50 %)".into(),
            y_label: "PC2".into(),
            points: vec![[-1.0, 0.0], [1.0, 0.5], [0.0, -2.0]],
            names: vec!["a<1>".into(), "b".into(), "c".into()],
            groups: vec![Some("Y".into()), Some("X".into()), None],
        }
    }

    #[test]
    fn svg_has_every_point_and_escapes_text() {
        let svg = scatter_svg(&sample());
        assert_eq!(svg.matches("<circle cx").count(), 3 + 2);
        assert!(svg.contains("PC1 &amp; PC2") && svg.contains("a&lt;1&gt;"));
        // X sorts first: the second specimen gets the first colour.
        let (keys, colours) = sample().colours();
        assert_eq!(keys, ["X", "Y"]);
        assert_eq!(colours, vec![PALETTE[1], PALETTE[0], UNGROUPED]);
    }

    #[test]
    fn raster_draws_points_in_their_colours() {
        let plot = sample();
        let img = scatter_raster(&plot, 400, 300);
        assert_eq!(img.pixels.len(), 3 * 400 * 300);
        let count = |c: [u8; 3]| img.pixels.chunks(3).filter(|p| *p == c).count();
        assert!(count(PALETTE[0]) > 4 && count(PALETTE[1]) > 4 && count(UNGROUPED) > 4);
    }
}
