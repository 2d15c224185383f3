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

/// SHA-256 of the file at `path` and its size in bytes; for a folder (a
/// slice stack) the hash of [`content_hash_folder`].
pub fn content_hash_file(path: &Path) -> std::io::Result<(String, u64)> {
    if path.is_dir() {
        return content_hash_folder(path);
    }
    content_hash_reader(std::fs::File::open(path)?)
}

/// SHA-256 over the slice files of the folder `dir` (by extension, hidden
/// files and other kinds such as logs left out, as the slice reader does),
/// in natural name order: for each, its name, its length and its bytes,
/// streamed file by file. Returns the hash and the total bytes of the
/// slices. The same slices under another folder name hash the same; a
/// renamed, changed, added or removed slice changes the hash.
fn content_hash_folder(dir: &Path) -> std::io::Result<(String, u64)> {
    let mut hasher = Sha256::new();
    // Keeps a folder's hash apart from any file whose bytes happen to
    // spell the same stream.
    hasher.update(b"morphoid slice folder\0");
    let mut total = 0u64;
    for path in crate::volume::slice_paths(dir)? {
        let name = path.file_name().map(|n| n.to_string_lossy().into_owned());
        let name = name.unwrap_or_default();
        let size = std::fs::metadata(&path)?.len();
        hasher.update((name.len() as u64).to_le_bytes());
        hasher.update(name.as_bytes());
        hasher.update(size.to_le_bytes());
        let mut file = std::fs::File::open(&path)?.take(size);
        let n = std::io::copy(&mut file, &mut hasher)?;
        if n != size {
            // Shrunk while being read: the folder is not settled.
            return Err(std::io::Error::new(
                std::io::ErrorKind::UnexpectedEof,
                format!("{}: changed while being read", path.display()),
            ));
        }
        total += n;
    }
    Ok((hex(&hasher.finalize()), total))
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

    #[test]
    fn folder_hash_follows_the_slices_not_the_folder_name_or_other_files() {
        let tmp = tempfile::tempdir().unwrap();
        let a = tmp.path().join("a");
        let b = tmp.path().join("b");
        for d in [&a, &b] {
            std::fs::create_dir(d).unwrap();
            for i in [1, 2, 10] {
                std::fs::write(d.join(format!("s{i}.tif")), [i as u8; 300]).unwrap();
            }
        }
        std::fs::write(b.join("scan.log"), b"not a slice").unwrap();
        let (ha, na) = content_hash_file(&a).unwrap();
        let (hb, nb) = content_hash_file(&b).unwrap();
        assert_eq!((ha.clone(), na), (hb, nb));
        assert_eq!(na, 900);
        std::fs::write(b.join("s10.tif"), [9u8; 300]).unwrap();
        assert_ne!(content_hash_file(&b).unwrap().0, ha);
        std::fs::rename(b.join("s10.tif"), b.join("s3.tif")).unwrap();
        std::fs::write(b.join("s3.tif"), [10u8; 300]).unwrap();
        assert_ne!(content_hash_file(&b).unwrap().0, ha, "renamed slice");
        std::fs::write(b.join("s11.tif"), [1u8; 3]).unwrap();
        assert_ne!(content_hash_file(&b).unwrap().0, ha);
    }
}
