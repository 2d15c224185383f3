//! Write the seed inputs of the fuzz targets, made from the synthetic
//! data, to `DIR/<target>/<name>` (`fuzz/campaign.sh` runs it).
//!
//! `cargo run --release --example fuzz_seeds -- DIR`

#[path = "../tests/it/support/fuzz_seeds.rs"]
mod fuzz_seeds;

fn main() -> std::io::Result<()> {
    let dir = std::env::args_os()
        .nth(1)
        .map(std::path::PathBuf::from)
        .ok_or_else(|| std::io::Error::other("usage: fuzz_seeds DIR"))?;
    let seeds = fuzz_seeds::seeds()?;
    for (target, name, bytes) in &seeds {
        let folder = dir.join(target);
        std::fs::create_dir_all(&folder)?;
        std::fs::write(folder.join(name), bytes)?;
    }
    println!("{} seeds in {}", seeds.len(), dir.display());
    Ok(())
}
