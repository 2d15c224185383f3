//! The per-scan report: one self-contained HTML page (pictures as PNG data
//! URIs, the 3D view's code and mesh data inline), so a file share or a
//! browser without network opens it.

use super::render::{render, Image};
use super::scene::Scene;
use super::{no_close_match, rank_confidence};
use crate::store::{ScanRecord, ScanStatus};
use base64::Engine;
use morphoid_core::clean::CleanReport;
use morphoid_data::present::escape;
use std::fmt::Write;

/// Side of the pictures in a report, in pixels.
pub(crate) const PICTURE_SIZE: usize = 360;

/// Side of the index's thumbnails, in pixels.
pub(crate) const THUMBNAIL_SIZE: usize = 96;

/// The viewer's code, inlined into every report.
const VIEWER_JS: &str = include_str!("viewer.js");

/// Shared style of the report and the index.
pub(super) const STYLE: &str = "body{font-family:system-ui,sans-serif;margin:1.5em;color:#222}\
table{border-collapse:collapse;margin:.5em 0}td,th{border:1px solid #ccc;padding:.25em .6em;\
text-align:left;vertical-align:top}th{background:#f3f3f3}.error{background:#fde8e8;\
border:2px solid #c00;padding:.8em;font-size:1.1em;white-space:pre-wrap}.note{background:#fff6dd;\
border:1px solid #c90;padding:.6em}.muted{color:#777}figure{display:inline-block;margin:.3em}\
figcaption{font-size:.9em;text-align:center}code{font-size:.9em}canvas{border:1px solid #ccc;\
max-width:100%}.ok{color:#070}.bad{color:#c00}";

/// An `<img>` of the picture, embedded as a data URI.
fn img_tag(image: &Image, alt: &str) -> String {
    match image.to_png() {
        Some(png) => format!(
            "<img width=\"{s}\" height=\"{s}\" alt=\"{}\" src=\"data:image/png;base64,{}\">",
            escape(alt),
            base64::engine::general_purpose::STANDARD.encode(png),
            s = image.size
        ),
        None => format!(
            "<p class=\"muted\">({} could not be drawn)</p>",
            escape(alt)
        ),
    }
}

/// The scan's thumbnail: coloured through its nearest reference's map,
/// plain grey without one.
pub fn thumbnail(scene: &Scene) -> Image {
    let colours = scene
        .pairings
        .first()
        .map(|p| p.carried.clone())
        .unwrap_or_default();
    render(
        &scene.scan.vertices,
        &scene.scan.faces,
        &colours,
        &scene.camera,
        THUMBNAIL_SIZE,
    )
}

/// A time in Unix milliseconds as `YYYY-MM-DD hh:mm:ss UTC`.
pub fn utc_time(ms: i64) -> String {
    let secs = ms.div_euclid(1000);
    let (days, rem) = (secs.div_euclid(86_400), secs.rem_euclid(86_400));
    // Civil date from days since 1970-01-01 (Howard Hinnant's algorithm).
    let z = days + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z - era * 146_097;
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let d = doy - (153 * mp + 2) / 5 + 1;
    let m = if mp < 10 { mp + 3 } else { mp - 9 };
    let y = yoe + era * 400 + i64::from(m <= 2);
    format!(
        "{y:04}-{m:02}-{d:02} {:02}:{:02}:{:02} UTC",
        rem / 3600,
        rem % 3600 / 60,
        rem % 60
    )
}

/// What a result without confidence says: identified while the library's
/// calibration was running, or the library is not calibrated.
pub(super) fn uncalibrated_text(calibrating: bool) -> &'static str {
    if calibrating {
        "confidence: calibrating"
    } else {
        "not calibrated"
    }
}

/// The text of a calibrated probability, or why there is none.
pub(super) fn confidence_text(p: Option<f64>, calibrating: bool) -> String {
    match p {
        Some(p) => format!("{:.0} %", p * 100.0),
        None => uncalibrated_text(calibrating).into(),
    }
}

/// The text of the "no close match" flag, or why there is none.
pub(super) fn novelty_text(flag: Option<bool>, calibrating: bool) -> &'static str {
    match flag {
        Some(true) => {
            "NO CLOSE MATCH: farther from the library than a known taxon's member would be"
        }
        Some(false) => "close match",
        None => uncalibrated_text(calibrating),
    }
}

/// The file name shown for a scan: its last path component.
pub fn file_name(path: &str) -> &str {
    path.rsplit(['/', '\\'])
        .find(|s| !s.is_empty())
        .unwrap_or(path)
}

/// The report page of a recorded scan: what it is, the error in plain
/// words if it failed, the answer per rank with distances (and the
/// calibrated confidence when the record has one), the nearest references,
/// the pictures and the 3D view of `scene` (when there is one), carried
/// landmarks, the cleaning report and timings. `note` says why something
/// is missing (e.g. the scan file is gone).
pub(crate) fn report_html(
    record: &ScanRecord,
    scene: Option<&Scene>,
    note: Option<&str>,
) -> String {
    let mut h = String::with_capacity(1 << 20);
    let name = file_name(&record.path);
    let _ = write!(
        h,
        "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">\
         <title>morphoid: {}</title><style>{STYLE}</style></head><body>\n\
         <h1>{}</h1>\n",
        escape(name),
        escape(name)
    );
    let shown = shown_status(record);
    let _ = write!(
        h,
        "<table id=\"scan\"><tr><th>File</th><td><code>{}</code></td></tr>\
         <tr><th>Status</th><td id=\"status\">{}</td></tr>\
         <tr><th>Scan id</th><td>{}</td></tr>\
         <tr><th>SHA-256</th><td><code>{}</code></td></tr>\
         <tr><th>Size</th><td>{} bytes</td></tr>\
         <tr><th>Queued</th><td>{}</td></tr>",
        escape(&record.path),
        escape(shown),
        record.id,
        escape(&record.content_hash),
        record.size,
        utc_time(record.created_at_ms),
    );
    if let Some(t) = record.finished_at_ms {
        let _ = write!(h, "<tr><th>Finished</th><td>{}</td></tr>", utc_time(t));
    }
    if let Some(o) = &record.duplicate_of {
        let _ = write!(
            h,
            "<tr><th>Duplicate of</th><td>scan {} (<code>{}</code>): the same content, \
             identified once</td></tr>",
            o.id,
            escape(&o.path)
        );
    }
    h.push_str("</table>\n");
    if let Some(e) = &record.files_error {
        let _ = writeln!(
            h,
            "<div class=\"error\" id=\"files-error\">The result files of this scan could not \
             be written: {} (the identification is recorded)</div>",
            escape(e)
        );
    }
    if let Some(note) = note {
        let _ = writeln!(h, "<p class=\"note\" id=\"note\">{}</p>", escape(note));
    }
    if record.specimen_count.is_some() {
        specimens(&mut h, record);
    }
    if let (Some(n), Some(p)) = (record.specimen, &record.position) {
        let voxels = p
            .voxels
            .map(|[lo, hi]| format!("voxels {lo:?}–{hi:?}, "))
            .unwrap_or_default();
        let _ = writeln!(
            h,
            "<p id=\"specimen\">Specimen {n} of the scan <code>{}</code> (scan {}): {}\
             coordinates {}–{}.</p>",
            escape(record.path.rsplit_once('#').map_or("", |(f, _)| f)),
            record.parent.unwrap_or_default(),
            escape(&voxels),
            escape(&format_point(p.bounds[0])),
            escape(&format_point(p.bounds[1]))
        );
    }
    match shown_status_kind(record) {
        _ if record.specimen_count.is_some() && record.status == ScanStatus::Ok => {}
        ScanStatus::Error => {
            let _ = writeln!(
                h,
                "<h2>Not identified</h2><div class=\"error\" id=\"error\">{}</div>",
                escape(record.error.as_deref().unwrap_or("(no message recorded)"))
            );
        }
        ScanStatus::Ok => identification(&mut h, record),
        _ => h.push_str("<p>Not identified yet.</p>\n"),
    }
    if let Some(scene) = scene {
        pictures(&mut h, scene);
        viewer(&mut h, scene);
    }
    landmarks(&mut h, record);
    cleaning(&mut h, &record.cleaning);
    timings(&mut h, record);
    h.push_str("</body></html>\n");
    h
}

/// `(x, y, z)` to two decimals.
fn format_point(p: [f64; 3]) -> String {
    format!("({:.2}, {:.2}, {:.2})", p[0], p[1], p[2])
}

/// The specimens of a scan of several: each one's number, position,
/// answer, and a link to its own report.
fn specimens(h: &mut String, record: &ScanRecord) {
    let _ = writeln!(
        h,
        "<h2>Specimens</h2>\n<p>{} specimens, numbered along the scan's longest axis; each \
         is identified on its own.</p>\n<table id=\"specimens\"><tr><th>Specimen</th>\
         <th>Status</th><th>Answer</th><th>Position (file coordinates)</th></tr>",
        record.specimen_count.unwrap_or(0)
    );
    for c in &record.specimens {
        let answer = match c.status {
            ScanStatus::Ok => c
                .ranks
                .iter()
                .map(|k| format!("{}: <b>{}</b>", escape(&k.rank), escape(&k.taxon)))
                .collect::<Vec<_>>()
                .join(", "),
            _ => escape(c.error.as_deref().unwrap_or("")),
        };
        let position = c
            .position
            .as_ref()
            .map(|p| {
                format!(
                    "{}–{}",
                    format_point(p.bounds[0]),
                    format_point(p.bounds[1])
                )
            })
            .unwrap_or_default();
        let page = super::href_of(&format!("{}.html", file_name(&c.path)));
        let _ = writeln!(
            h,
            "<tr><td><a href=\"{}\">{}</a></td><td>{}</td><td>{answer}</td><td>{}</td></tr>",
            escape(&page),
            escape(file_name(&c.path)),
            escape(c.status.as_str()),
            escape(&position)
        );
    }
    h.push_str("</table>\n");
}

/// The status a person reads (a duplicate's is its original's).
fn shown_status(record: &ScanRecord) -> &'static str {
    match (&record.status, &record.duplicate_of) {
        (ScanStatus::Duplicate, Some(o)) => match o.status {
            ScanStatus::Ok => "duplicate (identified)",
            ScanStatus::Error => "duplicate (error)",
            _ => "duplicate (waiting)",
        },
        (s, _) => s.as_str(),
    }
}

/// The status whose result the record carries.
fn shown_status_kind(record: &ScanRecord) -> ScanStatus {
    match (&record.status, &record.duplicate_of) {
        (ScanStatus::Duplicate, Some(o)) => o.status,
        (s, _) => *s,
    }
}

/// Per-rank answers and the nearest references.
fn identification(h: &mut String, record: &ScanRecord) {
    h.push_str(
        "<h2>Identification</h2>\n<table id=\"ranks\"><tr><th>Rank</th><th>Taxon</th>\
         <th>Confidence</th><th>Nearest reference</th><th>cP distance</th><th>Runner-up</th>\
         <th>Margin</th></tr>",
    );
    for r in &record.ranks {
        let _ = write!(
            h,
            "<tr><td>{}</td><td><b>{}</b></td><td class=\"confidence\">{}</td><td>{}</td>\
             <td>{:.4}</td><td>{}</td><td>{}</td></tr>",
            escape(&r.rank),
            escape(&r.taxon),
            confidence_text(rank_confidence(record, &r.rank), record.calibrating),
            escape(&r.reference),
            r.distance,
            escape(r.runner_up.as_deref().unwrap_or("—")),
            r.margin
                .map(|m| format!("{m:.4}"))
                .unwrap_or_else(|| "—".into()),
        );
    }
    let _ = writeln!(
        h,
        "</table>\n<p id=\"novelty\">Novelty: {}</p>",
        novelty_text(no_close_match(record), record.calibrating)
    );
    h.push_str(
        "<h3>Nearest references</h3>\n<table id=\"nearest\"><tr><th>#</th><th>Reference</th>\
         <th>cP distance</th></tr>",
    );
    for (i, n) in record.nearest.iter().enumerate() {
        let _ = write!(
            h,
            "<tr><td>{}</td><td>{}</td><td>{:.4}</td></tr>",
            i + 1,
            escape(&n.reference),
            n.distance
        );
    }
    h.push_str("</table>\n");
}

/// The scan and each nearest reference side by side, in the same pose.
fn pictures(h: &mut String, scene: &Scene) {
    h.push_str(
        "<h2>Scan and nearest references</h2>\n<p>Each reference is moved onto the scan by the \
         rigid part of its cP map and coloured by position (red: right, green: up, blue: toward \
         you); the scan beside it carries those colours through the cP correspondence, so \
         matching colours mean matching parts (cusps to cusps).</p>\n",
    );
    for p in &scene.pairings {
        let scan = render(
            &scene.scan.vertices,
            &scene.scan.faces,
            &p.carried,
            &scene.camera,
            PICTURE_SIZE,
        );
        let reference = render(
            &p.aligned.vertices,
            &p.aligned.faces,
            &p.aligned.colours,
            &scene.camera,
            PICTURE_SIZE,
        );
        let _ = writeln!(
            h,
            "<div class=\"pair\"><figure>{}<figcaption>scan, coloured through the map</figcaption>\
             </figure><figure>{}<figcaption>{} (cP distance {:.4}{})</figcaption></figure></div>",
            img_tag(&scan, "scan"),
            img_tag(&reference, &p.reference),
            escape(&p.reference),
            p.distance,
            if p.reflected { ", mirror image" } else { "" }
        );
    }
}

/// Little-endian bytes of `values` as base64.
fn base64_of<T: Copy, const N: usize>(values: &[T], bytes: impl Fn(T) -> [u8; N]) -> String {
    let raw: Vec<u8> = values.iter().flat_map(|&v| bytes(v)).collect();
    base64::engine::general_purpose::STANDARD.encode(raw)
}

/// The scene as the viewer's JSON (floats as f32, indices as u32, colours
/// as bytes; all base64), safe inside a `<script>` element.
pub(crate) fn scene_json(scene: &Scene) -> String {
    let points = |v: &[[f64; 3]]| {
        let flat: Vec<f32> = v.iter().flatten().map(|&x| x as f32).collect();
        base64_of(&flat, f32::to_le_bytes)
    };
    let faces = |f: &[[u32; 3]]| {
        let flat: Vec<u32> = f.iter().flatten().copied().collect();
        base64_of(&flat, u32::to_le_bytes)
    };
    let colours = |c: &[[u8; 3]]| {
        let flat: Vec<u8> = c.iter().flatten().copied().collect();
        base64::engine::general_purpose::STANDARD.encode(flat)
    };
    let pairs: Vec<serde_json::Value> = scene
        .pairings
        .iter()
        .map(|p| {
            serde_json::json!({
                "name": p.reference,
                "v": points(&p.aligned.vertices),
                "f": faces(&p.aligned.faces),
                "c": colours(&p.aligned.colours),
                "carried": colours(&p.carried),
            })
        })
        .collect();
    let cam = &scene.camera;
    let value = serde_json::json!({
        "scan": {"v": points(&scene.scan.vertices), "f": faces(&scene.scan.faces)},
        "pairs": pairs,
        "landmarks": scene.landmarks.iter().map(|l| l.position).collect::<Vec<_>>(),
        "camera": {"centre": cam.centre, "right": cam.right, "up": cam.up, "half": cam.half_extent},
    });
    // `</` would end the script element early.
    value.to_string().replace("</", "<\\/")
}

/// The interactive view: canvas, controls, the scene and the viewer code.
fn viewer(h: &mut String, scene: &Scene) {
    h.push_str("<h2>3D view</h2>\n<p><label>Reference: <select id=\"viewer-reference\">");
    for (i, p) in scene.pairings.iter().enumerate() {
        let _ = write!(
            h,
            "<option value=\"{i}\">{} ({:.4})</option>",
            escape(&p.reference),
            p.distance
        );
    }
    h.push_str(
        "</select></label> <label><input type=\"checkbox\" id=\"viewer-colours\" checked> \
         correspondence colours on the scan</label></p>\n\
         <canvas id=\"viewer\" width=\"880\" height=\"440\"></canvas>\n\
         <p id=\"viewer-check\" data-drawn=\"-1\" class=\"muted\">3D view needs JavaScript.</p>\n\
         <script type=\"application/json\" id=\"scene-data\">",
    );
    h.push_str(&scene_json(scene));
    h.push_str("</script>\n<script>\n");
    h.push_str(VIEWER_JS);
    h.push_str("</script>\n");
}

/// The carried landmarks, in the scan file's coordinates.
fn landmarks(h: &mut String, record: &ScanRecord) {
    let Some(lm) = &record.landmarks else {
        return;
    };
    let _ = write!(
        h,
        "<h2>Landmarks</h2>\n<p>Carried from <b>{}</b> through the cP correspondence; scan file \
         coordinates.</p>\n<table id=\"landmarks\"><tr><th>#</th><th>Label</th><th>x</th>\
         <th>y</th><th>z</th></tr>",
        escape(&lm.reference)
    );
    for (i, p) in lm.points.iter().enumerate() {
        let _ = write!(
            h,
            "<tr><td>{}</td><td>{}</td><td>{:.4}</td><td>{:.4}</td><td>{:.4}</td></tr>",
            i + 1,
            escape(p.label.as_deref().unwrap_or("")),
            p.x,
            p.y,
            p.z
        );
    }
    h.push_str("</table>\n");
}

/// The cleaning report: what was done, in words (the cleaning report as
/// recorded), then every recorded value under "all values".
fn cleaning(h: &mut String, report: &serde_json::Value) {
    if report.is_null() {
        return;
    }
    h.push_str(
        "<h2>Cleaning</h2>\n<p>What was done to the scan before it was compared.</p>\n\
         <table id=\"cleaning\">",
    );
    let warnings = report["warnings"].as_array().into_iter().flatten();
    for w in warnings.filter_map(|w| w.as_str()) {
        let _ = write!(h, "<tr><th>warning</th><td>{}</td></tr>", escape(w));
    }
    // A report of an older version may not read as today's: its raw
    // values below still say everything.
    if let Ok(r) = serde_json::from_value::<CleanReport>(report.clone()) {
        for (k, v) in super::cleaning::cleaning_rows(&r) {
            let _ = write!(h, "<tr><th>{}</th><td>{}</td></tr>", escape(k), escape(&v));
        }
    }
    h.push_str("</table>\n<details><summary>all values</summary>\n<table id=\"cleaning-values\">");
    let mut rows = Vec::new();
    flatten_json("", report, &mut rows);
    for (k, v) in rows {
        let _ = write!(h, "<tr><th>{}</th><td>{}</td></tr>", escape(&k), escape(&v));
    }
    h.push_str("</table></details>\n");
}

/// `(dotted key, text)` of each scalar in `value`.
fn flatten_json(prefix: &str, value: &serde_json::Value, out: &mut Vec<(String, String)>) {
    let key = |k: &str| {
        if prefix.is_empty() {
            k.to_string()
        } else {
            format!("{prefix}.{k}")
        }
    };
    match value {
        serde_json::Value::Object(m) => {
            for (k, v) in m {
                flatten_json(&key(k), v, out);
            }
        }
        serde_json::Value::Array(a) if a.iter().all(|v| !v.is_object() && !v.is_array()) => {
            let items: Vec<String> = a.iter().map(scalar_text).collect();
            out.push((prefix.to_string(), items.join(", ")));
        }
        serde_json::Value::Array(a) => {
            for (i, v) in a.iter().enumerate() {
                flatten_json(&key(&i.to_string()), v, out);
            }
        }
        v => out.push((prefix.to_string(), scalar_text(v))),
    }
}

/// A JSON scalar as text (strings without quotes, `—` for null).
fn scalar_text(v: &serde_json::Value) -> String {
    match v {
        serde_json::Value::String(s) => s.clone(),
        serde_json::Value::Null => "—".into(),
        v => v.to_string(),
    }
}

/// Milliseconds per stage.
fn timings(h: &mut String, record: &ScanRecord) {
    if record.timings_ms.is_empty() {
        return;
    }
    h.push_str("<h2>Timings</h2>\n<table id=\"timings\">");
    for (k, v) in &record.timings_ms {
        let _ = write!(h, "<tr><th>{}</th><td>{v:.0} ms</td></tr>", escape(k));
    }
    h.push_str("</table>\n");
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn times_are_civil_utc() {
        assert_eq!(utc_time(0), "1970-01-01 00:00:00 UTC");
        // 2024-02-29 12:34:56 UTC.
        assert_eq!(utc_time(1_709_210_096_000), "2024-02-29 12:34:56 UTC");
    }

    #[test]
    fn nested_reports_flatten_to_dotted_keys() {
        let v = serde_json::json!({"a": 1, "b": {"c": [1, 2], "d": null}, "e": [{"f": "x"}]});
        let mut rows = Vec::new();
        flatten_json("", &v, &mut rows);
        let rows: Vec<(&str, &str)> = rows.iter().map(|(a, b)| (a.as_str(), b.as_str())).collect();
        assert_eq!(
            rows,
            vec![("a", "1"), ("b.c", "1, 2"), ("b.d", "—"), ("e.0.f", "x")]
        );
    }

    #[test]
    fn file_names_are_the_last_component() {
        assert_eq!(file_name("/a/b/x.ply"), "x.ply");
        assert_eq!(file_name("C:\\s\\y.stl"), "y.stl");
        assert_eq!(file_name("slices/"), "slices");
    }
}
