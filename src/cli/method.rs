//! `--method`: which distance `distance` and `matrix` compute, and the
//! options of the cWn and cW distances.

use morphoid_core::cw::CwParams;
use morphoid_core::cwn::CwnParams;

/// The distance between two surfaces.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, clap::ValueEnum)]
pub(super) enum Method {
    /// Continuous Procrustes distance (extrinsic; the default).
    #[default]
    Cp,
    /// Conformal Wasserstein neighbourhood dissimilarity distance
    /// (intrinsic, research use).
    Cwn,
    /// Conformal Wasserstein distance: optimal transport of the conformal
    /// densities, minimized over Möbius maps of the disk (intrinsic,
    /// research use).
    Cw,
    /// The discrete Procrustes distance between the landmark files of the
    /// library (`landmarks/<name>.{csv,fcsv,mrk.json,pp}`): the paper's ODLP
    /// (`matrix` only).
    Landmarks,
}

impl Method {
    /// The name used in outputs (`cp`, `cwn`, `cw`, `landmarks`).
    pub(super) fn name(self) -> &'static str {
        match self {
            Method::Cp => "cp",
            Method::Cwn => "cwn",
            Method::Cw => "cw",
            Method::Landmarks => "landmarks",
        }
    }
}

/// Options of the cWn distance (ignored by the other methods).
#[derive(Debug, Clone, clap::Args)]
pub(super) struct CwnArgs {
    /// cWn: Euclidean radius R of the neighbourhoods in the disk (0 < R < 1).
    #[arg(long, value_name = "R", default_value_t = CwnParams::default().radius)]
    cwn_radius: f64,
    /// cWn: compare neighbourhoods by rotations only, not mirror images.
    #[arg(long)]
    cwn_no_reflections: bool,
}

impl CwnArgs {
    /// The cWn parameters these options select (checked when used).
    pub(super) fn params(&self) -> CwnParams {
        CwnParams {
            radius: self.cwn_radius,
            reflections: !self.cwn_no_reflections,
            ..CwnParams::default()
        }
    }
}

/// Options of the cW distance (ignored by the other methods).
#[derive(Debug, Clone, clap::Args)]
pub(super) struct CwArgs {
    /// cW: search orientation-preserving maps only, not mirror images.
    #[arg(long)]
    cw_no_reflections: bool,
}

impl CwArgs {
    /// The cW parameters these options select (checked when used).
    pub(super) fn params(&self) -> CwParams {
        CwParams {
            reflections: !self.cw_no_reflections,
            ..CwParams::default()
        }
    }
}
