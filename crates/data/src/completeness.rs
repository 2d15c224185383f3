//! Whether a scan file is complete by its own format: a header that
//! declares more than the bytes hold means another program is still
//! writing it. One pure function per format over the bytes (or the slice
//! names); [`check_path`] reads the file and picks one. Formats that cannot
//! tell (OBJ, NRRD, NIfTI, image slices) are [`Verdict::Unknown`]: the
//! daemon's settle time decides for them. A file that is malformed rather
//! than short is `Complete` here: the reader reports what is wrong.

use crate::mesh_io::Format;
use std::path::Path;

/// What a file's format says about its completeness.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Verdict {
    /// Everything the header declares is there (or the file is malformed
    /// in a way more bytes cannot mend).
    Complete,
    /// The header declares more than the file holds: why, in words.
    Incomplete(String),
    /// The format cannot tell.
    Unknown,
}

/// The verdict for the scan at `path` (a surface file or a slice folder),
/// by its format; reads the file. I/O errors are returned (the file may
/// have vanished).
pub fn check_path(path: &Path) -> std::io::Result<Verdict> {
    if path.is_dir() {
        // DICOM files are told apart by their positions, not their names
        // (series are often named by UID or by an unrelated counter).
        let (dicom, images): (Vec<_>, Vec<_>) = crate::volume::slice_paths(path)?
            .into_iter()
            .partition(|p| {
                crate::volume::slice_format(p) == Some(crate::volume::VolumeFormat::Dicom)
            });
        if !dicom.is_empty() {
            if let Some(positions) = crate::volume::slice_positions_along_normal(&dicom) {
                let verdict = dicom_positions(&positions);
                if verdict != Verdict::Unknown {
                    return Ok(verdict);
                }
            }
        }
        let names: Vec<Option<u64>> = images.iter().map(|p| trailing_number(p)).collect();
        return Ok(slice_numbers(&names));
    }
    let Some(format) = Format::from_path(path) else {
        return Ok(Verdict::Unknown);
    };
    let bytes = std::fs::read(path)?;
    if bytes.is_empty() {
        // Nothing written yet, or an empty file: the settle time decides.
        return Ok(Verdict::Unknown);
    }
    Ok(match format {
        Format::Stl => stl(&bytes),
        Format::Ply => ply(&bytes),
        Format::Off => off(&bytes),
        Format::Obj => Verdict::Unknown,
    })
}

/// The number at the end of a file stem (`slice_0042.tif` → 42).
fn trailing_number(path: &Path) -> Option<u64> {
    let stem = path.file_stem()?.to_str()?;
    let digits = stem.len() - stem.trim_end_matches(|c: char| c.is_ascii_digit()).len();
    stem.get(stem.len() - digits..)?.parse().ok()
}

/// A binary STL shorter than `84 + 50·n` bytes for the `n` triangles its
/// header declares, or an ASCII STL without its closing `endsolid`.
pub fn stl(bytes: &[u8]) -> Verdict {
    let text = bytes.iter().take(4096).all(|&b| b != 0 && b < 0x80);
    let begins_solid = bytes
        .iter()
        .position(|b| !b.is_ascii_whitespace())
        .and_then(|s| bytes.get(s..s + 5))
        .is_some_and(|w| w.eq_ignore_ascii_case(b"solid"));
    if begins_solid && text {
        let last = bytes
            .split(|&b| b == b'\n')
            .rev()
            .map(|l| l.trim_ascii())
            .find(|l| !l.is_empty())
            .unwrap_or(&[]);
        let ends = last.len() >= 8 && last[..8].eq_ignore_ascii_case(b"endsolid");
        return if ends {
            Verdict::Complete
        } else {
            Verdict::Incomplete("ASCII STL without its closing 'endsolid' yet".into())
        };
    }
    let Some(c) = bytes.get(80..84) else {
        return Verdict::Incomplete(format!(
            "{} bytes, shorter than a binary STL's 84-byte header",
            bytes.len()
        ));
    };
    let n = u64::from(u32::from_le_bytes([c[0], c[1], c[2], c[3]]));
    let needed = 84 + 50 * n;
    if needed > MAX_PLAUSIBLE_BYTES {
        // Not a count any export has: not STL at all, which no more
        // bytes will mend (the reader says what is wrong).
        Verdict::Complete
    } else if (bytes.len() as u64) < needed {
        Verdict::Incomplete(format!(
            "binary STL of {n} triangles needs {needed} bytes, the file has {}",
            bytes.len()
        ))
    } else {
        Verdict::Complete
    }
}

/// The largest binary STL taken as plausibly still being written (the
/// readers' own limit on a file's size).
const MAX_PLAUSIBLE_BYTES: u64 = 2 << 30;

/// A PLY whose header is not finished, or whose declared elements do not
/// fit in the bytes that follow (binary) or the lines (ASCII).
pub fn ply(bytes: &[u8]) -> Verdict {
    if !b"ply".starts_with(&bytes[..bytes.len().min(3)]) {
        // Not PLY, however long it grows.
        return Verdict::Complete;
    }
    let Some(end) = find(bytes, b"end_header") else {
        return Verdict::Incomplete("PLY header without 'end_header' yet".into());
    };
    let Some(nl) = bytes[end..].iter().position(|&b| b == b'\n') else {
        return Verdict::Incomplete("PLY header without 'end_header' yet".into());
    };
    let header = String::from_utf8_lossy(&bytes[..end]);
    let body = &bytes[end + nl + 1..];
    let mut format = "";
    let mut elements: Vec<PlyElement> = Vec::new();
    for line in header.lines() {
        let w: Vec<&str> = line.split_whitespace().collect();
        match w.as_slice() {
            ["format", f, ..] => format = f,
            ["element", name, n] => match n.parse() {
                Ok(n) => elements.push((name.to_string(), n, Vec::new(), Vec::new())),
                Err(_) => return Verdict::Complete,
            },
            ["property", "list", c, i, _] => {
                match (type_size(c), type_size(i), elements.last_mut()) {
                    (Some(c), Some(i), Some(e)) => {
                        e.2.push(Some((c, i)));
                        e.3.push(0)
                    }
                    _ => return Verdict::Complete,
                }
            }
            ["property", t, _] => match (type_size(t), elements.last_mut()) {
                (Some(s), Some(e)) => {
                    e.2.push(None);
                    e.3.push(s)
                }
                _ => return Verdict::Complete,
            },
            _ => {}
        }
    }
    let declared: u64 = elements.iter().map(|e| e.1).sum();
    // Each row takes a byte at least: a count no export reaches is a
    // malformed header, not a file still growing.
    if declared > MAX_PLAUSIBLE_BYTES {
        return Verdict::Complete;
    }
    if format == "ascii" {
        let lines = body
            .split(|&b| b == b'\n')
            .filter(|l| !l.trim_ascii().is_empty())
            .count() as u64;
        return if lines < declared {
            Verdict::Incomplete(format!(
                "ASCII PLY declares {declared} element lines, {lines} are there"
            ))
        } else if !body.ends_with(b"\n") && lines == declared {
            Verdict::Incomplete("ASCII PLY's last line is not finished".into())
        } else {
            Verdict::Complete
        };
    }
    let big = format == "binary_big_endian";
    if !big && format != "binary_little_endian" {
        return Verdict::Complete;
    }
    let mut at = 0usize;
    for (name, n, props, sizes) in &elements {
        for row in 0..*n {
            for (p, s) in props.iter().zip(sizes) {
                let step = match p {
                    None => Some(*s),
                    Some((c, i)) => body.get(at..at + c).map(|b| {
                        let k = uint(b, big);
                        c + usize::try_from(k)
                            .unwrap_or(usize::MAX / 2)
                            .saturating_mul(*i)
                    }),
                };
                match step.and_then(|s| at.checked_add(s)) {
                    Some(next) if next <= body.len() => at = next,
                    _ => {
                        return Verdict::Incomplete(format!(
                            "binary PLY ends in {name} {row} of the {n} it declares \
                             ({} bytes after the header)",
                            body.len()
                        ))
                    }
                }
            }
        }
    }
    Verdict::Complete
}

/// A PLY element as declared: its name, count, properties (`None`: a
/// scalar; `Some((count size, item size))`: a list) and scalar sizes.
type PlyElement = (String, u64, Vec<Option<(usize, usize)>>, Vec<usize>);

/// Size in bytes of a PLY scalar type.
fn type_size(t: &str) -> Option<usize> {
    Some(match t {
        "char" | "uchar" | "int8" | "uint8" => 1,
        "short" | "ushort" | "int16" | "uint16" => 2,
        "int" | "uint" | "float" | "int32" | "uint32" | "float32" => 4,
        "double" | "float64" => 8,
        _ => return None,
    })
}

/// An unsigned integer of 1, 2 or 4 bytes (a list count).
fn uint(b: &[u8], big: bool) -> u64 {
    let mut v = 0u64;
    for k in 0..b.len() {
        let byte = if big { b[k] } else { b[b.len() - 1 - k] };
        v = (v << 8) | u64::from(byte);
    }
    v
}

fn find(hay: &[u8], needle: &[u8]) -> Option<usize> {
    hay.windows(needle.len()).position(|w| w == needle)
}

/// An OFF whose vertex and face counts are not met by its lines, or whose
/// last face line is not finished.
pub fn off(bytes: &[u8]) -> Verdict {
    let text = String::from_utf8_lossy(bytes);
    let mut lines = text
        .lines()
        .map(|l| l.split('#').next().unwrap_or("").trim())
        .filter(|l| !l.is_empty());
    let Some(first) = lines.next() else {
        return Verdict::Incomplete("empty OFF file".into());
    };
    let mut words: Vec<&str> = first.split_whitespace().collect();
    if words.first().is_some_and(|w| w.ends_with("OFF")) {
        words.remove(0);
    }
    if words.is_empty() {
        match lines.next() {
            Some(l) => words = l.split_whitespace().collect(),
            None => return Verdict::Incomplete("OFF file without its counts yet".into()),
        }
    }
    let (Some(nv), Some(nf)) = (
        words.first().and_then(|w| w.parse::<u64>().ok()),
        words.get(1).and_then(|w| w.parse::<u64>().ok()),
    ) else {
        return Verdict::Complete;
    };
    if nv.saturating_add(nf) > MAX_PLAUSIBLE_BYTES {
        return Verdict::Complete;
    }
    let rest: Vec<&str> = lines.collect();
    let have = rest.len() as u64;
    if have < nv + nf {
        return Verdict::Incomplete(format!(
            "OFF declares {nv} vertices and {nf} faces ({} lines), {have} are there",
            nv + nf
        ));
    }
    if nf > 0 && have == nv + nf {
        // The last face line: its corner count and that many indices.
        let last: Vec<&str> = rest[rest.len() - 1].split_whitespace().collect();
        let corners = last.first().and_then(|w| w.parse::<usize>().ok());
        if corners.is_some_and(|k| last.len() < k + 1)
            || !bytes.ends_with(b"\n") && corners.is_none()
        {
            return Verdict::Incomplete("OFF's last face line is not finished".into());
        }
    }
    Verdict::Complete
}

/// A slice folder whose numbered slices (the numbers at the end of their
/// names, in natural order) skip a number: slices still arriving. Folders
/// whose slices are not all numbered cannot tell.
pub(crate) fn slice_numbers(numbers: &[Option<u64>]) -> Verdict {
    let Some(mut sorted) = numbers.iter().copied().collect::<Option<Vec<u64>>>() else {
        return Verdict::Unknown;
    };
    sorted.sort_unstable();
    sorted.dedup();
    match sorted.windows(2).find(|w| w[1] > w[0] + 1) {
        Some(w) => Verdict::Incomplete(format!(
            "slices numbered up to {} but {} to {} are missing",
            sorted[sorted.len() - 1],
            w[0] + 1,
            w[1] - 1
        )),
        None => Verdict::Unknown,
    }
}

/// A DICOM series whose slice positions along the normal leave a gap: a
/// step more than 1.5 times the usual (median) one.
pub(crate) fn dicom_positions(positions: &[f64]) -> Verdict {
    let mut p: Vec<f64> = positions
        .iter()
        .copied()
        .filter(|x| x.is_finite())
        .collect();
    if p.len() < 3 {
        return Verdict::Unknown;
    }
    p.sort_by(f64::total_cmp);
    let steps: Vec<f64> = p.windows(2).map(|w| w[1] - w[0]).collect();
    let mut sorted = steps.clone();
    sorted.sort_by(f64::total_cmp);
    let usual = sorted[sorted.len() / 2];
    if usual <= 0.0 {
        return Verdict::Unknown;
    }
    match steps.iter().position(|&s| s > 1.5 * usual) {
        Some(i) => Verdict::Incomplete(format!(
            "DICOM slice positions jump from {:.4} to {:.4} (usual step {usual:.4}): \
             slices missing",
            p[i],
            p[i + 1]
        )),
        // Evenly spaced says nothing of slices still to come at either end.
        None => Verdict::Unknown,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn incomplete(v: Verdict) -> bool {
        matches!(v, Verdict::Incomplete(_))
    }

    #[test]
    fn binary_and_ascii_stl() {
        let mut b = vec![0u8; 80];
        b.extend_from_slice(&2u32.to_le_bytes());
        b.extend_from_slice(&[1u8; 50]);
        assert!(incomplete(stl(&b)), "one of two triangles");
        b.extend_from_slice(&[1u8; 50]);
        assert_eq!(stl(&b), Verdict::Complete);
        assert!(incomplete(stl(&b[..40])));
        // Random bytes declare an absurd count: not STL, not waited for.
        let mut random = vec![7u8; 80];
        random.extend_from_slice(&u32::MAX.to_le_bytes());
        assert_eq!(stl(&random), Verdict::Complete);
        let ascii = b"solid t\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\n";
        assert!(incomplete(stl(ascii)));
        let mut done = ascii.to_vec();
        done.extend_from_slice(b"endloop\nendfacet\nendsolid t\n");
        assert_eq!(stl(&done), Verdict::Complete);
    }

    #[test]
    fn ply_elements_must_fit() {
        let head = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\n\
                    property float y\nproperty float z\nelement face 1\n\
                    property list uchar int vertex_indices\nend_header\n";
        assert!(incomplete(ply(&head.as_bytes()[..30])));
        assert_eq!(ply(b"not a ply file"), Verdict::Complete);
        let huge = "ply\nformat binary_little_endian 1.0\nelement vertex 4000000000\n\
                    property float x\nend_header\n";
        assert_eq!(ply(huge.as_bytes()), Verdict::Complete);
        let full = format!("{head}0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n");
        assert_eq!(ply(full.as_bytes()), Verdict::Complete);
        assert!(incomplete(ply(&full.as_bytes()[..full.len() - 9])));
        let bin_head = head.replace("ascii", "binary_little_endian");
        let mut bin = bin_head.into_bytes();
        for v in [[0f32, 0., 0.], [1., 0., 0.], [0., 1., 0.]] {
            for c in v {
                bin.extend_from_slice(&c.to_le_bytes());
            }
        }
        bin.push(3);
        for i in [0i32, 1, 2] {
            bin.extend_from_slice(&i.to_le_bytes());
        }
        assert_eq!(ply(&bin), Verdict::Complete);
        assert!(incomplete(ply(&bin[..bin.len() - 1])));
        assert!(incomplete(ply(&bin[..bin.len() - 20])));
    }

    #[test]
    fn off_counts_must_be_met() {
        let full = "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n";
        assert_eq!(off(full.as_bytes()), Verdict::Complete);
        assert!(incomplete(off(&full.as_bytes()[..full.len() - 9])));
        assert!(incomplete(off(b"OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1")));
        assert!(incomplete(off(b"OFF\n")));
        assert_eq!(
            off(b"OFF 3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n"),
            Verdict::Complete
        );
    }

    #[test]
    fn slice_numbering_and_dicom_positions_with_gaps() {
        assert_eq!(
            slice_numbers(&[Some(1), Some(2), Some(3)]),
            Verdict::Unknown
        );
        assert!(incomplete(slice_numbers(&[Some(1), Some(2), Some(5)])));
        assert_eq!(slice_numbers(&[Some(1), None]), Verdict::Unknown);
        assert_eq!(dicom_positions(&[0.0, 0.5, 1.0, 1.5]), Verdict::Unknown);
        assert!(incomplete(dicom_positions(&[0.0, 0.5, 1.0, 2.5])));
    }
}
