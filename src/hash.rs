//! Content hashes: the identity of a scan or reference mesh file.
//!
//! A file is known by what it holds, not by its name or time stamp: the
//! same bytes under a new name are the same scan, changed bytes under the
//! same name are a new one. The hash is SHA-256, written as 64 lower-case
//! hexadecimal digits.

use sha2::{Digest, Sha256};
use std::io::Read;
use std::path::Path;

/// SHA-256 of `bytes` as 64 lower-case hexadecimal digits.
pub fn content_hash(bytes: &[u8]) -> String {
    hex(&Sha256::digest(bytes))
}

/// SHA-256 of everything `reader` yields, read in blocks (a large scan is
/// never held in memory whole). Returns the hash and the number of bytes.
fn content_hash_reader<R: Read>(mut reader: R) -> std::io::Result<(String, u64)> {
    let mut hasher = Sha256::new();
    let mut buffer = vec![0u8; 1 << 16];
    let mut total = 0u64;
    loop {
        let n = match reader.read(&mut buffer) {
            Ok(0) => break,
            Ok(n) => n,
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => continue,
            Err(e) => return Err(e),
        };
        let block = buffer.get(..n).unwrap_or(&[]);
        hasher.update(block);
        total += n as u64;
    }
    Ok((hex(&hasher.finalize()), total))
}

/// SHA-256 of the file at `path` and its size in bytes.
pub fn content_hash_file(path: &Path) -> std::io::Result<(String, u64)> {
    content_hash_reader(std::fs::File::open(path)?)
}

/// `bytes` as lower-case hexadecimal digits, two per byte.
pub(crate) fn hex(bytes: &[u8]) -> String {
    const DIGITS: &[u8; 16] = b"0123456789abcdef";
    let mut out = String::with_capacity(bytes.len() * 2);
    for &byte in bytes {
        out.push(DIGITS[usize::from(byte >> 4)] as char);
        out.push(DIGITS[usize::from(byte & 0x0f)] as char);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn known_vectors() {
        // FIPS 180-2 test vectors.
        assert_eq!(
            content_hash(b""),
            "e3b0c44298fc1c149afbf4c8996fb92427ae41e4649b934ca495991b7852b855"
        );
        assert_eq!(
            content_hash(b"abc"),
            "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad"
        );
    }

    #[test]
    fn reader_matches_slice_across_blocks() {
        let data: Vec<u8> = (0..200_000u32).map(|i| (i * 7 % 251) as u8).collect();
        let (hash, n) = content_hash_reader(&data[..]).expect("in-memory read");
        assert_eq!(n, data.len() as u64);
        assert_eq!(hash, content_hash(&data));
        assert_ne!(hash, content_hash(&data[1..]));
    }
}
