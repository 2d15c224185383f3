//! The overview page of a results folder: scans newest first, each with its
//! status, thumbnail, taxon per rank, confidence, flags and error, linking
//! to its report. `index.html` holds the most recent [`INDEX_RECENT`];
//! older scans are on pages of [`INDEX_PAGE`] scan ids each, written once
//! (see `ResultFiles::write_index`), so updating the overview costs the
//! same with ten or ten thousand scans.

use super::html::{confidence_text, file_name, utc_time, STYLE};
use super::{no_close_match, rank_confidence};
use crate::store::{ScanRecord, ScanStatus};
use morphoid_data::present::escape;
use std::fmt::Write;

/// Scans on `index.html`.
pub(crate) const INDEX_RECENT: usize = 100;

/// Scan ids per older page.
pub(crate) const INDEX_PAGE: i64 = 100;

/// One row of the overview: a scan and where its report and thumbnail are
/// (relative links).
#[derive(Debug, Clone, Copy)]
pub(crate) struct IndexRow<'a> {
    /// The scan.
    pub record: &'a ScanRecord,
    /// Its report.
    pub report: &'a str,
    /// Its thumbnail, when it has one.
    pub thumbnail: Option<&'a str>,
}

/// A link to another page of the overview.
#[derive(Debug, Clone)]
pub(crate) struct PageLink {
    /// Relative link.
    pub href: String,
    /// What it holds (e.g. "scans 101–200").
    pub label: String,
}

/// Percent-encoding of a relative path for an `href` (`/` kept).
pub(crate) fn href_of(path: &str) -> String {
    let mut out = String::with_capacity(path.len());
    for b in path.bytes() {
        match b {
            b'A'..=b'Z' | b'a'..=b'z' | b'0'..=b'9' | b'-' | b'_' | b'.' | b'~' | b'/' => {
                out.push(char::from(b))
            }
            b => {
                let _ = write!(out, "%{b:02X}");
            }
        }
    }
    out
}

/// The file name of the older page holding scan ids
/// `(k·INDEX_PAGE, (k+1)·INDEX_PAGE]`.
pub(crate) fn page_name(k: i64) -> String {
    format!("index-{:06}.html", k)
}

/// The overview page: `title`, the rows (newest first), links to `pages`.
pub(crate) fn index_html(title: &str, rows: &[IndexRow<'_>], pages: &[PageLink]) -> String {
    let mut h = String::with_capacity(64 * 1024 + rows.len() * 600);
    let _ = write!(
        h,
        "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">\
         <title>morphoid: {t}</title><style>{STYLE}</style></head><body>\n<h1>{t}</h1>\n\
         <table id=\"scans\"><tr><th>Scan</th><th>Status</th><th></th><th>File</th>\
         <th>Taxon per rank</th><th>Confidence</th><th>Flags</th><th>Finished</th></tr>\n",
        t = escape(title)
    );
    for row in rows {
        index_row(&mut h, row);
    }
    h.push_str("</table>\n");
    if !pages.is_empty() {
        h.push_str("<h2>Older scans</h2>\n<ul id=\"pages\">");
        for p in pages {
            let _ = write!(
                h,
                "<li><a href=\"{}\">{}</a></li>",
                escape(&p.href),
                escape(&p.label)
            );
        }
        h.push_str("</ul>\n");
    }
    h.push_str("</body></html>\n");
    h
}

/// One `<tr>` of the overview.
fn index_row(h: &mut String, row: &IndexRow<'_>) {
    let r = row.record;
    let (status, result_status) = match (&r.status, &r.duplicate_of) {
        (ScanStatus::Duplicate, Some(o)) => ("duplicate", o.status),
        (s, _) => (s.as_str(), *s),
    };
    let class = match result_status {
        ScanStatus::Ok => "ok",
        ScanStatus::Error => "bad",
        _ => "muted",
    };
    let thumb = row
        .thumbnail
        .map(|t| {
            format!(
                "<img loading=\"lazy\" width=\"48\" height=\"48\" alt=\"\" src=\"{}\">",
                escape(t)
            )
        })
        .unwrap_or_default();
    let (taxa, confidence) = if let Some(n) = r.specimen_count {
        // A scan of several specimens: its rows follow, one per specimen.
        let failed = r
            .specimens
            .iter()
            .filter(|c| c.status == ScanStatus::Error)
            .count();
        let text = if failed > 0 {
            format!("{n} specimens ({failed} not identified), listed below")
        } else {
            format!("{n} specimens, listed below")
        };
        (text, String::new())
    } else if result_status == ScanStatus::Ok {
        let taxa: Vec<String> = r
            .ranks
            .iter()
            .map(|k| format!("{}: <b>{}</b>", escape(&k.rank), escape(&k.taxon)))
            .collect();
        let conf: Vec<String> = r
            .ranks
            .iter()
            .map(|k| confidence_text(rank_confidence(r, &k.rank), r.calibrating))
            .collect();
        (taxa.join("<br>"), conf.join("<br>"))
    } else if result_status == ScanStatus::Error {
        (
            format!(
                "<span class=\"bad\">{}</span>",
                escape(r.error.as_deref().unwrap_or("error"))
            ),
            String::new(),
        )
    } else {
        (String::new(), String::new())
    };
    let mut flags = Vec::new();
    if let Some(n) = r.specimen {
        flags.push(format!("specimen {n}"));
    }
    if r.duplicate_of.is_some() {
        flags.push("duplicate".to_string());
    }
    if no_close_match(r) == Some(true) {
        flags.push("<b class=\"bad\">no close match</b>".to_string());
    }
    if r.landmarks.is_some() {
        flags.push("landmarks".to_string());
    }
    if let Some(e) = &r.files_error {
        flags.push(format!(
            "<span class=\"bad files-error\">result files not written: {}</span>",
            escape(e)
        ));
    }
    let _ = writeln!(
        h,
        "<tr><td><a href=\"{}\">{}</a></td><td class=\"{class}\">{}</td><td>{thumb}</td>\
         <td><a href=\"{}\">{}</a></td><td>{taxa}</td><td>{confidence}</td><td>{}</td><td>{}</td></tr>",
        escape(row.report),
        r.id,
        escape(status),
        escape(row.report),
        escape(file_name(&r.path)),
        flags.join(", "),
        r.finished_at_ms.map(utc_time).unwrap_or_default(),
    );
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hrefs_encode_what_urls_reserve() {
        assert_eq!(href_of("a b/x#1.ply.html"), "a%20b/x%231.ply.html");
        assert_eq!(href_of("ü.html"), "%C3%BC.html");
    }
}
