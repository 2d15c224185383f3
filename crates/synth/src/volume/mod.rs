//! Synthetic volumes for tests, benchmarks and the demo: a closed whole
//! tooth voxelized with a brighter enamel layer under its crown faces,
//! dentine below, blurred ([`phantom`]); written with noise as slice
//! stacks and volume files of any size ([`write_volume`]); several
//! together in foam ([`batch_in_foam`]); a real crown mounted in foam,
//! a tube, wax and a pin as loose teeth are scanned, alone or in a batch
//! ([`mounting`]).

mod batch;
pub mod mounting;
mod phantom;
mod write;

pub use batch::batch_in_foam;
pub use phantom::{phantom, PhantomParams};
pub use write::{write_volume, StackSpec, SynthFormat};
