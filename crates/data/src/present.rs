//! What every module that shows something to a person shares, written
//! once: text put into HTML, SVG or XML ([`escape`]), pictures as PNG bytes
//! ([`png_bytes`]) and an error with its causes on one line
//! ([`error_chain`]). Pure functions over plain data.

/// `s` with the characters HTML and XML give meaning to (`&`, `<`, `>`,
/// `"` and `'`) escaped, so that it can stand in element text and in
/// attribute values quoted either way.
pub fn escape(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    for c in s.chars() {
        match c {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            // `&apos;` is not HTML 4; the numeric reference is read by both.
            '\'' => out.push_str("&#39;"),
            c => out.push(c),
        }
    }
    out
}

/// How the bytes of a picture hold its pixels: 8 bits a channel, row
/// after row from the top.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Channels {
    /// Red, green, blue: 3 bytes a pixel.
    Rgb,
    /// Red, green, blue, alpha: 4 bytes a pixel.
    Rgba,
}

/// A `width` × `height` picture as PNG bytes; an error when `pixels` is
/// not `width · height` pixels of `channels`.
pub fn png_bytes(
    width: u32,
    height: u32,
    channels: Channels,
    pixels: &[u8],
) -> Result<Vec<u8>, png::EncodingError> {
    let mut out = Vec::new();
    let mut encoder = png::Encoder::new(&mut out, width, height);
    encoder.set_color(match channels {
        Channels::Rgb => png::ColorType::Rgb,
        Channels::Rgba => png::ColorType::Rgba,
    });
    encoder.set_depth(png::BitDepth::Eight);
    // Smooth shading and flat colour fields: the fast encoder's size is
    // close to the default's at a fraction of its time, which counts for
    // the report written after every scan.
    encoder.set_compression(png::Compression::Fast);
    let mut writer = encoder.write_header()?;
    writer.write_image_data(pixels)?;
    writer.finish()?;
    Ok(out)
}

/// `e` and its causes on one line, `: `-separated. A text the line
/// already ends with is not repeated: errors here name their source in
/// their own message, so that a log line of `{e}` is complete, and the
/// chain adds only what the message leaves out.
pub fn error_chain(e: &dyn std::error::Error) -> String {
    let mut line = String::new();
    for cause in std::iter::successors(Some(e), |c| c.source()) {
        let text = cause.to_string();
        if line.ends_with(&text) {
            continue;
        }
        if !line.is_empty() {
            line.push_str(": ");
        }
        line.push_str(&text);
    }
    line
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn escape_covers_markup_and_both_quotes() {
        assert_eq!(
            escape("<a href=\"x\">&'"),
            "&lt;a href=&quot;x&quot;&gt;&amp;&#39;"
        );
        assert_eq!(escape("plain é"), "plain é");
    }

    #[test]
    fn png_round_trips_both_layouts() {
        for (channels, n) in [(Channels::Rgb, 3), (Channels::Rgba, 4)] {
            let pixels: Vec<u8> = (0..5 * 3 * n).map(|i| (i * 7) as u8).collect();
            let bytes = png_bytes(5, 3, channels, &pixels).unwrap();
            let decoder = png::Decoder::new(std::io::Cursor::new(bytes));
            let mut reader = decoder.read_info().unwrap();
            let mut buf = vec![0; reader.output_buffer_size().unwrap()];
            let info = reader.next_frame(&mut buf).unwrap();
            assert_eq!((info.width, info.height), (5, 3));
            assert_eq!(&buf[..info.buffer_size()], &pixels[..]);
        }
        assert!(png_bytes(5, 3, Channels::Rgb, &[0; 7]).is_err());
    }

    #[derive(Debug, thiserror::Error)]
    #[error("{text}")]
    struct Layer {
        text: String,
        #[source]
        source: Option<Box<Layer>>,
    }

    fn layers(texts: &[&str]) -> Layer {
        let (first, rest) = texts.split_first().unwrap();
        Layer {
            text: first.to_string(),
            source: (!rest.is_empty()).then(|| Box::new(layers(rest))),
        }
    }

    #[test]
    fn a_chain_names_each_cause_once() {
        assert_eq!(
            error_chain(&layers(&[
                "cannot load the library /lib",
                "permission denied"
            ])),
            "cannot load the library /lib: permission denied"
        );
        // A message that already ends with its cause's text.
        assert_eq!(
            error_chain(&layers(&["x.ply: cannot read: bad header", "bad header"])),
            "x.ply: cannot read: bad header"
        );
        assert_eq!(error_chain(&layers(&["alone"])), "alone");
    }
}
