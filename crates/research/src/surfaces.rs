//! The distance matrix of a folder of prepared surfaces, by either
//! surface distance (cP, cWn or cW).

use morphoid_core::cp::ParamError;
use morphoid_core::cp::Prepared;
use morphoid_core::cw::{self, CwError, CwParams};
use morphoid_core::cwn::{self, CwnError, CwnParams, Landscape};
use morphoid_data::pipeline::Settings;
use morphoid_data::table::{distance_matrix, pairwise_matrix, DistanceMatrix};
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
            SurfaceDistance::Cp => Ok(distance_matrix(prepared, &settings.cp.compare, progress)),
            SurfaceDistance::Cwn(params) => {
                self.validate()?;
                let landscapes = prepared
                    .par_iter()
                    .map(|p| landscape(p, params))
                    .collect::<Result<Vec<_>, _>>()?;
                cwn_matrix(&landscapes, params, progress).map_err(SurfaceMatrixError::Cwn)
            }
            SurfaceDistance::Cw(params) => {
                cw_matrix(prepared, params, progress).map_err(SurfaceMatrixError::Cw)
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

/// The symmetric matrix of cW distances between all pairs (zero
/// diagonal; pair `i < j` computed as `distance(i, j)`), pairs in
/// parallel; `progress` receives the number of pairs done so far. The
/// values do not depend on the number of threads.
pub fn cw_matrix(
    prepared: &[Prepared],
    params: &CwParams,
    progress: impl Fn(usize) + Sync,
) -> Result<DistanceMatrix, CwError> {
    params.validate()?;
    let names = prepared.iter().map(|p| p.name().to_string()).collect();
    pairwise_matrix(
        names,
        |i, j| Ok(cw::distance(&prepared[i], &prepared[j], params)?.distance),
        progress,
    )
}

/// The symmetric matrix of cWn distances between all pairs of landscapes
/// (zero diagonal), pairs in parallel; `progress` receives the number of
/// pairs done so far. The values do not depend on the number of threads.
pub fn cwn_matrix(
    landscapes: &[Landscape],
    params: &CwnParams,
    progress: impl Fn(usize) + Sync,
) -> Result<DistanceMatrix, CwnError> {
    let names = landscapes.iter().map(|l| l.name().to_string()).collect();
    pairwise_matrix(
        names,
        |i, j| Ok(cwn::distance(&landscapes[i], &landscapes[j], params)?.distance),
        progress,
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use morphoid_core::cp::{self, PrepareParams};
    use morphoid_synth::mesh::{crown as synthetic_crown, CROWN_GENERA};

    fn crown(genus: usize, seed: u64) -> Prepared {
        let m = synthetic_crown(&CROWN_GENERA[genus], seed, 1500);
        cp::prepare(&m, &PrepareParams::default()).expect("a synthetic crown prepares")
    }

    #[test]
    fn cw_matrix_matches_pairwise_distances() {
        let params = CwParams::default();
        let ps: Vec<Prepared> = (0..3)
            .map(|g| {
                let mut p = crown(g, 2);
                p.set_name(format!("s{g}"));
                p
            })
            .collect();
        let m = cw_matrix(&ps, &params, |_| {}).unwrap();
        assert_eq!(m.names(), vec!["s0", "s1", "s2"]);
        for i in 0..3 {
            assert_eq!(m.values()[i][i], 0.0);
            for j in i + 1..3 {
                let d = cw::distance(&ps[i], &ps[j], &params).unwrap().distance;
                assert_eq!(m.values()[i][j], d);
                assert_eq!(m.values()[j][i], d);
            }
        }
    }
    #[test]
    fn cwn_matrix_matches_pairwise_distances() {
        let params = CwnParams::default();
        let ls: Vec<Landscape> = (0..3)
            .map(|g| {
                let mut p = crown(g, 2);
                p.set_name(format!("s{g}"));
                cwn::prepare(&p, &params).unwrap()
            })
            .collect();
        let m = cwn_matrix(&ls, &params, |_| {}).unwrap();
        assert_eq!(m.names(), vec!["s0", "s1", "s2"]);
        for i in 0..3 {
            assert_eq!(m.values()[i][i], 0.0);
            for j in i + 1..3 {
                let d = cwn::distance(&ls[i], &ls[j], &params).unwrap().distance;
                assert_eq!(m.values()[i][j], d);
                assert_eq!(m.values()[j][i], d);
            }
        }
    }
}
