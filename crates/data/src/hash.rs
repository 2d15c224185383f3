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

/// The identity of content that was read: its hash (as
/// [`content_hash_file`] gives it) and its size in bytes.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Content {
    /// 64 lower-case hexadecimal digits.
    pub hash: String,
    /// Bytes (for a slice folder, of all its slices).
    pub size: u64,
}

impl Content {
    /// The identity of `bytes`, a whole file.
    pub fn of(bytes: &[u8]) -> Content {
        Content {
            hash: content_hash(bytes),
            size: bytes.len() as u64,
        }
    }
}

/// A SHA-256 being computed over bytes as they are read, shared between
/// a [`HashingReader`] buried in a reader chain and whoever finishes it.
#[derive(Debug, Clone, Default)]
pub(crate) struct SharedHash(std::sync::Arc<std::sync::Mutex<(Sha256, u64)>>);

impl SharedHash {
    /// A hash of nothing yet.
    pub(crate) fn new() -> Self {
        Self::default()
    }

    fn update(&self, bytes: &[u8]) {
        let mut state = self.0.lock().unwrap_or_else(|p| p.into_inner());
        state.0.update(bytes);
        state.1 += bytes.len() as u64;
    }

    /// The content of every byte read so far.
    pub(crate) fn content(&self) -> Content {
        let state = self.0.lock().unwrap_or_else(|p| p.into_inner());
        Content {
            hash: hex(&state.0.clone().finalize()),
            size: state.1,
        }
    }
}

/// A reader that hashes every byte it hands on, so that what a parser
/// reads from a file (streamed, never held whole) and the content hash
/// are of the same bytes.
#[derive(Debug)]
pub(crate) struct HashingReader<R> {
    inner: R,
    hash: Option<SharedHash>,
}

impl<R> HashingReader<R> {
    /// `inner`, hashed into `hash` as it is read.
    #[cfg(test)]
    fn new(inner: R, hash: SharedHash) -> Self {
        Self::maybe(inner, Some(hash))
    }

    /// `inner`, hashed into `hash` when there is one (readers that hash
    /// only when asked share one code path).
    pub(crate) fn maybe(inner: R, hash: Option<SharedHash>) -> Self {
        HashingReader { inner, hash }
    }
}

impl<R: Read> Read for HashingReader<R> {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        let n = self.inner.read(buf)?;
        if let Some(hash) = &self.hash {
            hash.update(buf.get(..n).unwrap_or(&[]));
        }
        Ok(n)
    }
}

/// The hash of a slice folder ([`content_hash_file`] of a folder) computed
/// from slices that a reader holds in memory one at a time, in natural
/// name order.
#[derive(Debug, Clone)]
pub(crate) struct FolderHash {
    hasher: Sha256,
    total: u64,
}

impl Default for FolderHash {
    fn default() -> Self {
        Self::new()
    }
}

impl FolderHash {
    /// The hash of a folder with no slices yet.
    pub(crate) fn new() -> Self {
        let mut hasher = Sha256::new();
        hasher.update(FOLDER_PREFIX);
        FolderHash { hasher, total: 0 }
    }

    /// Add the next slice (in natural name order): its file name and bytes.
    pub(crate) fn slice(&mut self, name: &str, bytes: &[u8]) {
        folder_entry(&mut self.hasher, name, bytes.len() as u64);
        self.hasher.update(bytes);
        self.total += bytes.len() as u64;
    }

    /// The folder's content.
    pub(crate) fn finish(self) -> Content {
        Content {
            hash: hex(&self.hasher.finalize()),
            size: self.total,
        }
    }
}

/// What starts a folder's hash: keeps it apart from any file whose bytes
/// happen to spell the same stream.
const FOLDER_PREFIX: &[u8] = b"morphoid slice folder\0";

/// The part of a folder's hash before a slice's bytes: its name and size.
fn folder_entry(hasher: &mut Sha256, name: &str, size: u64) {
    hasher.update((name.len() as u64).to_le_bytes());
    hasher.update(name.as_bytes());
    hasher.update(size.to_le_bytes());
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
    hasher.update(FOLDER_PREFIX);
    let mut total = 0u64;
    for path in crate::volume::slice_paths(dir)? {
        let name = path.file_name().map(|n| n.to_string_lossy().into_owned());
        let name = name.unwrap_or_default();
        let size = std::fs::metadata(&path)?.len();
        folder_entry(&mut hasher, &name, size);
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
pub fn hex(bytes: &[u8]) -> String {
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
        // Slices hashed from memory, in order, give the folder's hash.
        let mut folder = FolderHash::new();
        for p in crate::volume::slice_paths(&b).unwrap() {
            let name = p.file_name().unwrap().to_string_lossy().into_owned();
            folder.slice(&name, &std::fs::read(&p).unwrap());
        }
        let (hb, nb) = content_hash_file(&b).unwrap();
        assert_eq!(folder.finish(), Content { hash: hb, size: nb });
    }

    #[test]
    fn a_hashing_reader_hashes_what_it_hands_on() {
        let data: Vec<u8> = (0..100_000u32).map(|i| (i % 253) as u8).collect();
        let hash = SharedHash::new();
        let mut reader = HashingReader::new(&data[..], hash.clone());
        let mut head = [0u8; 1000];
        reader.read_exact(&mut head).unwrap();
        assert_eq!(hash.content(), Content::of(&data[..1000]));
        std::io::copy(&mut reader, &mut std::io::sink()).unwrap();
        assert_eq!(hash.content(), Content::of(&data));
    }
}
