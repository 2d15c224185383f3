//! The distance matrix of a folder of prepared surfaces, by either
//! surface distance (cP, cWn or cW).

use crate::cp::ParamError;
use crate::cp::Prepared;
use crate::cw::{self, CwError, CwParams};
use crate::cwn::{self, CwnError, CwnParams, Landscape};
use crate::eval::{self, DistanceMatrix};
use crate::pipeline::Settings;
use rayon::prelude::*;

/// A distance between prepared surfaces.
#[derive(Debug, Clone, PartialEq)]
pub enum SurfaceDistance {
    /// The continuous Procrustes distance (with the settings' engine
    /// parameters).
    Cp,
    /// The conformal Wasserstein neighbourhood dissimilarity distance.
    Cwn(CwnParams),
    /// The conformal Wasserstein distance.
    Cw(CwParams),
}

/// Why a matrix of surfaces cannot be computed.
#[derive(Debug, thiserror::Error)]
pub enum SurfaceMatrixError {
    /// The cWn parameters are invalid.
    #[error(transparent)]
    Params(ParamError),
    /// The cWn landscape of one surface cannot be built.
    #[error("{name}: {source}")]
    Landscape {
        /// The surface.
        name: String,
        /// Why.
        #[source]
        source: CwnError,
    },
    /// Two landscapes cannot be compared.
    #[error(transparent)]
    Cwn(CwnError),
    /// Two surfaces cannot be compared by cW.
    #[error(transparent)]
    Cw(CwError),
}

impl SurfaceDistance {
    /// The name used in outputs (`cp`, `cwn`, `cw`).
    pub fn name(&self) -> &'static str {
        match self {
            SurfaceDistance::Cp => "cp",
            SurfaceDistance::Cwn(_) => "cwn",
            SurfaceDistance::Cw(_) => "cw",
        }
    }

    /// Check the parameters (before hours of preparation).
    pub fn validate(&self) -> Result<(), SurfaceMatrixError> {
        match self {
            SurfaceDistance::Cp => Ok(()),
            SurfaceDistance::Cwn(params) => params.validate().map_err(SurfaceMatrixError::Params),
            SurfaceDistance::Cw(params) => params.validate().map_err(SurfaceMatrixError::Params),
        }
    }

    /// The symmetric matrix of this distance over all pairs of `prepared`
    /// (zero diagonal), pairs in parallel; `progress` receives the number
    /// of pairs done so far. The values do not depend on the number of
    /// threads.
    pub fn matrix(
        &self,
        prepared: &[Prepared],
        settings: &Settings,
        progress: impl Fn(usize) + Sync,
    ) -> Result<DistanceMatrix, SurfaceMatrixError> {
        match self {
            SurfaceDistance::Cp => Ok(eval::distance_matrix(
                prepared,
                &settings.cp.compare,
                progress,
            )),
            SurfaceDistance::Cwn(params) => {
                self.validate()?;
                let landscapes = prepared
                    .par_iter()
                    .map(|p| landscape(p, params))
                    .collect::<Result<Vec<_>, _>>()?;
                cwn::distance_matrix(&landscapes, params, progress).map_err(SurfaceMatrixError::Cwn)
            }
            SurfaceDistance::Cw(params) => {
                cw::distance_matrix(prepared, params, progress).map_err(SurfaceMatrixError::Cw)
            }
        }
    }
}

/// The cWn landscape of one prepared surface; the error names it.
pub fn landscape(prepared: &Prepared, params: &CwnParams) -> Result<Landscape, SurfaceMatrixError> {
    cwn::prepare(prepared, params).map_err(|source| SurfaceMatrixError::Landscape {
        name: prepared.name().to_string(),
        source,
    })
}
