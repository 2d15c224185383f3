//! `--method`: which distance a command computes.

/// The distance of `morphoid matrix` (and the commands that take a method).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, clap::ValueEnum)]
pub enum Method {
    /// The continuous Procrustes distance between the surfaces.
    #[default]
    Cp,
    /// The discrete Procrustes distance between the landmark files of the
    /// library (`landmarks/<name>.{csv,fcsv,mrk.json,pp}`): the paper's ODLP.
    Landmarks,
}
