//! What every module that shows something to a person shares, written
//! once: text put into HTML, SVG or XML ([`escape`]) and an error with
//! its causes on one line ([`error_chain`]). Pure functions over plain
//! data.

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
