//! Reports a person reads: a self-contained HTML page per scan (the scan
//! and its nearest references drawn in the same pose, the correspondence
//! as colours, an offline 3D view, the answers, cleaning and timings) and
//! an overview page of the results folder.
//!
//! `render` is a small z-buffer rasterizer (plain data to RGBA), `scene`
//! what is drawn (computed from the prepared scan and references), `html`
//! the report page, `index` the overview; the viewer is `viewer.js`,
//! inlined into each report. Writing the files is `classify::ResultFiles`'
//! job.

mod cleaning;
mod html;
mod index;
mod render;
mod scene;

pub(crate) use html::report_html;
pub use html::utc_time;
pub use html::{file_name, thumbnail};
pub(crate) use index::{
    href_of, index_html, page_name, IndexRow, PageLink, INDEX_PAGE, INDEX_RECENT,
};
pub use render::{render, unit, vertex_normals};
pub use scene::{Scene, SceneReference};

use crate::store::ScanRecord;

// The one place reports and the overview read the calibrated confidence
// and the "no close match" flag from; `None` is shown as "not calibrated".

/// The calibrated probability that the nearest taxon at `rank` is right
/// (`None`: not calibrated).
pub(crate) fn rank_confidence(record: &ScanRecord, rank: &str) -> Option<f64> {
    record
        .ranks
        .iter()
        .find(|r| r.rank == rank)?
        .confidence
        .as_ref()
        .map(|c| c.probability)
}

/// Whether the scan is farther from the library than a member of a known
/// taxon would be (`None`: not calibrated).
pub fn no_close_match(record: &ScanRecord) -> Option<bool> {
    record.no_close_match()
}
