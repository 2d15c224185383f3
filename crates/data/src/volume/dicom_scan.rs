//! The framing of a DICOM file, walked before dicom-object parses it:
//! dicom-object allocates (and zeroes) each element's declared length
//! before it reads the value, so a corrupt length field in a file of a
//! few hundred bytes would cost up to 4 GB. This walk visits every element
//! header the parser would read (file meta group, then the data set in
//! its transfer syntax: sequences and items entered, encapsulated
//! fragments skipped) and refuses a length longer than the bytes left.
//! A data set whose framing the walk cannot follow to its end (an item
//! where none may be, an end before the current position, bytes or an
//! open sequence left over at the end) is refused too: the parser would
//! read on from a place the walk did not check.

use dicom_core::dictionary::{DataDictionary, DataDictionaryEntry};
use dicom_core::{Tag, VR};
use dicom_dictionary_std::StandardDataDictionary;
use std::io::Read;

/// Transfer syntaxes of the data set's encoding.
const IMPLICIT_VR_LE: &str = "1.2.840.10008.1.2";
const EXPLICIT_VR_LE: &str = "1.2.840.10008.1.2.1";
const DEFLATED_EXPLICIT_VR_LE: &str = "1.2.840.10008.1.2.1.99";

/// Largest inflated data set of a deflated file (bytes): a 4096 × 4096
/// 16-bit slice and room for its header. The syntax is rare in CT; a
/// larger bound lets a 1 MB file cost seconds and hundreds of MB.
const MAX_INFLATED: u64 = 40 << 20;

/// An undefined length.
const UNDEFINED: u32 = u32::MAX;

/// A DICOM file's data set, its framing checked: where the walk began is
/// where the parser is to begin, so that the two read the same elements.
pub(crate) struct DataSet<'a> {
    /// The transfer syntax UID of the file meta group.
    pub syntax: String,
    /// The data set's bytes (inflated for the deflated syntax); empty for
    /// syntaxes that are not walked.
    pub bytes: std::borrow::Cow<'a, [u8]>,
    /// The transfer syntax `bytes` are encoded in as the parser is to
    /// read them: the file's, or explicit VR little endian once inflated.
    pub encoding: &'static str,
    /// Where the top-level pixel data element starts in `bytes`, if any.
    pub pixel_data: Option<usize>,
}

/// Walk the framing of the DICOM file `bytes`: its transfer syntax when
/// the file meta group can be read (the data set is walked only for the
/// syntaxes the reader takes), `None` when it cannot (the parser reports
/// why), or what is wrong when a length runs past the end.
#[cfg(test)]
fn transfer_syntax_checked(bytes: &[u8]) -> Result<Option<String>, String> {
    Ok(data_set_checked(bytes)?.map(|d| d.syntax))
}

/// The data set of the DICOM file `bytes` with its framing walked: the
/// transfer syntax when the file meta group can be read (the data set is
/// walked only for the syntaxes the reader takes), `None` when it cannot,
/// or what is wrong when a length runs past the end or the framing cannot
/// be followed.
pub(crate) fn data_set_checked(bytes: &[u8]) -> Result<Option<DataSet<'_>>, String> {
    let start = if bytes.get(128..132) == Some(b"DICM") {
        132
    } else if bytes.get(..4) == Some(b"DICM") {
        4
    } else {
        return Ok(None);
    };
    let Some((syntax, end)) = meta_group(bytes, start)? else {
        return Ok(None);
    };
    let rest = &bytes[end..];
    let (bytes, encoding, pixel_data) = match syntax.as_str() {
        IMPLICIT_VR_LE => (rest.into(), IMPLICIT_VR_LE, data_set(rest, end, false)?),
        EXPLICIT_VR_LE => (rest.into(), EXPLICIT_VR_LE, data_set(rest, end, true)?),
        DEFLATED_EXPLICIT_VR_LE => {
            let mut inflated = Vec::new();
            flate2::read::DeflateDecoder::new(rest)
                .take(MAX_INFLATED + 1)
                .read_to_end(&mut inflated)
                .map_err(|e| format!("the deflated data set cannot be inflated: {e}"))?;
            if inflated.len() as u64 > MAX_INFLATED {
                return Err(format!(
                    "the deflated data set inflates to more than {MAX_INFLATED} bytes"
                ));
            }
            let pixel_data = data_set(&inflated, 0, true)?;
            (inflated.into(), EXPLICIT_VR_LE, pixel_data)
        }
        _ => (std::borrow::Cow::Borrowed(&[][..]), EXPLICIT_VR_LE, None),
    };
    Ok(Some(DataSet {
        syntax,
        bytes,
        encoding,
        pixel_data,
    }))
}

fn u16_at(b: &[u8], at: usize) -> Option<u16> {
    Some(u16::from_le_bytes(b.get(at..at + 2)?.try_into().ok()?))
}

fn u32_at(b: &[u8], at: usize) -> Option<u32> {
    Some(u32::from_le_bytes(b.get(at..at + 4)?.try_into().ok()?))
}

/// An element header: tag, VR (explicit, or from the dictionary), value
/// length, header bytes.
struct Header {
    tag: Tag,
    vr: VR,
    len: u32,
    size: usize,
}

/// The explicit-VR little-endian header at `at`, as the parser decodes
/// it (group FFFE: no VR; an unknown VR reads as UN).
fn explicit_header(b: &[u8], at: usize) -> Option<Header> {
    let tag = Tag(u16_at(b, at)?, u16_at(b, at + 2)?);
    if tag.0 == 0xFFFE {
        return Some(Header {
            tag,
            vr: VR::UN,
            len: u32_at(b, at + 4)?,
            size: 8,
        });
    }
    let vr = VR::from_binary([*b.get(at + 4)?, *b.get(at + 5)?]).unwrap_or(VR::UN);
    use VR::*;
    let short = matches!(
        vr,
        AE | AS
            | AT
            | CS
            | DA
            | DS
            | DT
            | FL
            | FD
            | IS
            | LO
            | LT
            | PN
            | SH
            | SL
            | SS
            | ST
            | TM
            | UI
            | UL
            | US
    );
    Some(if short {
        Header {
            tag,
            vr,
            len: u32::from(u16_at(b, at + 6)?),
            size: 8,
        }
    } else {
        Header {
            tag,
            vr,
            len: u32_at(b, at + 8)?,
            size: 12,
        }
    })
}

/// The implicit-VR little-endian header at `at`, its VR from the
/// dictionary as the parser takes it.
fn implicit_header(b: &[u8], at: usize) -> Option<Header> {
    let tag = Tag(u16_at(b, at)?, u16_at(b, at + 2)?);
    let vr = if tag == Tag(0x7FE0, 0x0010) || (tag.0 >> 8 == 0x60 && tag.1 == 0x3000) {
        VR::OW
    } else {
        StandardDataDictionary
            .by_tag(tag)
            .map(|e| e.vr().relaxed())
            .unwrap_or(VR::UN)
    };
    Some(Header {
        tag,
        vr,
        len: u32_at(b, at + 4)?,
        size: 8,
    })
}

/// Error unless `len` bytes follow the header that ends at `at` (of
/// `total`); `offset` places `b` in the file for the message.
fn check(h: &Header, at: usize, total: usize, offset: usize) -> Result<(), String> {
    let left = total - at;
    // The parser reads a binary VR in whole values and leaves a remainder
    // unread: it would go on out of step with the framing.
    let size = match h.vr {
        VR::US | VR::SS | VR::OW => 2,
        VR::UL | VR::SL | VR::FL | VR::AT | VR::OL | VR::OF => 4,
        VR::FD | VR::OD | VR::SV | VR::UV | VR::OV => 8,
        _ => 1,
    };
    if h.len != UNDEFINED && !h.len.is_multiple_of(size) {
        return Err(format!(
            "element ({:04X},{:04X}) at byte {} of VR {} holds {} bytes, not a whole number \
             of {size}-byte values (corrupt file)",
            h.tag.0,
            h.tag.1,
            offset + at - h.size,
            h.vr.to_string(),
            h.len
        ));
    }
    if h.len as usize > left {
        return Err(format!(
            "element ({:04X},{:04X}) at byte {} declares {} bytes, but only {left} follow \
             (truncated or corrupt file)",
            h.tag.0,
            h.tag.1,
            offset + at - h.size,
            h.len
        ));
    }
    Ok(())
}

/// The file meta group from `start` as the parser reads it (explicit VR,
/// its length from (0002,0000)): the transfer syntax and where the data
/// set starts, or `None` where the parser would fail.
fn meta_group(b: &[u8], start: usize) -> Result<Option<(String, usize)>, String> {
    let Some(first) = explicit_header(b, start) else {
        return Ok(None);
    };
    if first.tag != Tag(0x0002, 0x0000) || first.len != 4 {
        return Ok(None);
    }
    let mut at = start + first.size;
    let Some(group_length) = u32_at(b, at) else {
        return Ok(None);
    };
    at += 4;
    let (mut read, mut syntax) = (0u32, None);
    while read < group_length {
        let Some(h) = explicit_header(b, at) else {
            return Ok(None);
        };
        if h.len == UNDEFINED {
            return Ok(None);
        }
        at += h.size;
        check(&h, at, b.len(), 0)?;
        if h.tag == Tag(0x0002, 0x0010) {
            let value = String::from_utf8_lossy(&b[at..at + h.len as usize]);
            syntax = Some(
                value
                    .trim_end_matches(|c: char| c.is_whitespace() || c == '\0')
                    .to_string(),
            );
        }
        at += h.len as usize;
        read = read.saturating_add(h.size as u32).saturating_add(h.len);
    }
    Ok(syntax.map(|s| (s, at)))
}

/// What is open around the current position: a sequence (of items, or
/// of encapsulated pixel data fragments) or an item, and where it ends
/// when its length is defined.
#[derive(Clone, Copy)]
enum Open {
    Sequence { fragments: bool, end: Option<usize> },
    Item { end: Option<usize> },
}

/// Why the data set's framing cannot be followed at byte `at` (of the file).
fn broken(at: usize, why: &str) -> String {
    format!("the data set's framing is broken at byte {at}: {why} (corrupt or truncated file)")
}

/// Walk the data set `b` (at byte `offset` of the file, for messages) as
/// the parser's state machine does: element headers and values; after a
/// sequence header, item headers; items hold elements, except those of
/// encapsulated pixel data, which hold bytes. A sequence or item of
/// defined length ends where its length says.
fn data_set(b: &[u8], offset: usize, explicit: bool) -> Result<Option<usize>, String> {
    let header = |at| {
        if explicit {
            explicit_header(b, at)
        } else {
            implicit_header(b, at)
        }
    };
    let end_of = |at: usize, len: u32| (len != UNDEFINED).then(|| at.saturating_add(len as usize));
    let mut open: Vec<Open> = Vec::new();
    let mut at = 0;
    let mut pixel_data = None;
    // Whether an item header (or the sequence's end) comes next.
    let mut in_sequence = false;
    loop {
        while let Some(&top) = open.last() {
            let (end, item) = match top {
                Open::Sequence { end, .. } => (end, false),
                Open::Item { end } => (end, true),
            };
            match end {
                Some(e) if e == at => {
                    open.pop();
                    in_sequence = item;
                }
                Some(e) if e < at => {
                    return Err(broken(
                        offset + at,
                        &format!("a sequence or item ends at byte {}, before it", offset + e),
                    ))
                }
                _ => break,
            }
        }
        if in_sequence {
            let (Some(group), Some(element), Some(len)) =
                (u16_at(b, at), u16_at(b, at + 2), u32_at(b, at + 4))
            else {
                return Err(broken(
                    offset + at,
                    "the data ends inside a sequence (truncated file)",
                ));
            };
            at += 8;
            match (group, element) {
                (0xFFFE, 0xE000) => {
                    let fragments = matches!(
                        open.last(),
                        Some(Open::Sequence {
                            fragments: true,
                            ..
                        })
                    );
                    if fragments {
                        if len == UNDEFINED {
                            return Err(broken(
                                offset + at - 8,
                                "a pixel data fragment of undefined length",
                            ));
                        }
                        let h = Header {
                            tag: Tag(group, element),
                            vr: VR::OB,
                            len,
                            size: 8,
                        };
                        check(&h, at, b.len(), offset)?;
                        at += len as usize;
                    } else {
                        in_sequence = false;
                        open.push(Open::Item {
                            end: end_of(at, len),
                        });
                    }
                }
                (0xFFFE, 0xE00D) => {
                    open.pop();
                }
                (0xFFFE, 0xE0DD) => {
                    open.pop();
                    in_sequence = false;
                }
                _ => {
                    return Err(broken(
                        offset + at - 8,
                        &format!("({group:04X},{element:04X}) where an item belongs"),
                    ))
                }
            }
            continue;
        }
        let Some(h) = header(at) else {
            if at == b.len() && open.is_empty() {
                return Ok(pixel_data);
            }
            return Err(broken(
                offset + at,
                if open.is_empty() {
                    "the data ends inside an element header (truncated file)"
                } else {
                    "the data ends inside a sequence (truncated file)"
                },
            ));
        };
        if h.tag == Tag(0x7FE0, 0x0010) && open.is_empty() && pixel_data.is_none() {
            pixel_data = Some(at);
        }
        at += h.size;
        if h.vr == VR::SQ {
            open.push(Open::Sequence {
                fragments: false,
                end: end_of(at, h.len),
            });
            in_sequence = true;
        } else if h.tag == Tag(0xFFFE, 0xE00D) {
            // An item's end; ignored outside any sequence.
            if open.pop().is_some() {
                in_sequence = true;
            }
        } else if h.len == UNDEFINED {
            // Encapsulated pixel data holds fragments; any other element
            // of undefined length is read as a sequence of items.
            open.push(Open::Sequence {
                fragments: h.tag == Tag(0x7FE0, 0x0010),
                end: None,
            });
            in_sequence = true;
        } else {
            check(&h, at, b.len(), offset)?;
            at += h.len as usize;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A file meta group naming `syntax`, after the preamble and magic.
    fn meta(syntax: &str) -> Vec<u8> {
        let mut uid = syntax.as_bytes().to_vec();
        if uid.len() % 2 == 1 {
            uid.push(0);
        }
        let mut element = vec![0x02, 0x00, 0x10, 0x00, b'U', b'I'];
        element.extend((uid.len() as u16).to_le_bytes());
        element.extend(&uid);
        let mut b = vec![0u8; 128];
        b.extend(b"DICM");
        b.extend([0x02, 0x00, 0x00, 0x00, b'U', b'L', 4, 0]);
        b.extend((element.len() as u32).to_le_bytes());
        b.extend(element);
        b
    }

    #[test]
    fn lengths_past_the_end_are_refused_and_fitting_ones_pass() {
        let mut b = meta(EXPLICIT_VR_LE);
        // Rows (US, 2 bytes), then an OB element of 4 GB - 2 in a short file.
        b.extend([0x28, 0x00, 0x10, 0x00, b'U', b'S', 2, 0, 64, 0]);
        assert_eq!(
            transfer_syntax_checked(&b),
            Ok(Some(EXPLICIT_VR_LE.to_string()))
        );
        b.extend([0x09, 0x00, 0x10, 0x00, b'O', b'B', 0, 0]);
        b.extend(0xFFFF_FFFEu32.to_le_bytes());
        b.extend([0u8; 16]);
        let e = transfer_syntax_checked(&b).unwrap_err();
        assert!(
            e.contains("(0009,0010)") && e.contains("4294967294") && e.contains("16 follow"),
            "{e}"
        );
    }

    #[test]
    fn elements_inside_sequences_and_implicit_data_sets_are_checked() {
        // Implicit VR: a sequence (ReferencedImageSequence, SQ in the
        // dictionary) of undefined length whose item holds a long element.
        let mut b = meta(IMPLICIT_VR_LE);
        b.extend([0x08, 0x00, 0x40, 0x11]);
        b.extend(UNDEFINED.to_le_bytes());
        b.extend([0xFE, 0xFF, 0x00, 0xE0]);
        b.extend(UNDEFINED.to_le_bytes());
        b.extend([0x08, 0x00, 0x50, 0x11]);
        b.extend(1_000_000u32.to_le_bytes());
        let e = transfer_syntax_checked(&b).unwrap_err();
        assert!(e.contains("(0008,1150)") && e.contains("1000000"), "{e}");
    }

    #[test]
    fn binary_values_must_be_whole() {
        // A group length (UL) of 2 bytes: the parser would read no value
        // and go on two bytes out of step.
        let mut b = meta(IMPLICIT_VR_LE);
        b.extend([0x28, 0x00, 0x00, 0x00, 2, 0, 0, 0, 1, 2]);
        let e = transfer_syntax_checked(&b).unwrap_err();
        assert!(
            e.contains("(0028,0000)") && e.contains("VR UL holds 2 bytes"),
            "{e}"
        );
    }

    #[test]
    fn framing_the_walk_cannot_follow_is_refused() {
        // An element of undefined length (read as a sequence) followed by
        // something other than an item.
        let mut b = meta(IMPLICIT_VR_LE);
        b.extend([0x09, 0x00, 0x10, 0x00]);
        b.extend(UNDEFINED.to_le_bytes());
        b.extend([0x28, 0x00, 0x10, 0x00, 2, 0, 0, 0, 64, 0]);
        let e = transfer_syntax_checked(&b).unwrap_err();
        assert!(e.contains("(0028,0010) where an item belongs"), "{e}");
        // A data set that stops inside an element header.
        let mut c = meta(EXPLICIT_VR_LE);
        c.extend([0x28, 0x00, 0x10, 0x00, b'U']);
        let e = transfer_syntax_checked(&c).unwrap_err();
        assert!(e.contains("inside an element header"), "{e}");
        // A sequence left open at the end.
        let mut d = meta(EXPLICIT_VR_LE);
        d.extend([0x08, 0x00, 0x40, 0x11, b'S', b'Q', 0, 0]);
        d.extend(UNDEFINED.to_le_bytes());
        let e = transfer_syntax_checked(&d).unwrap_err();
        assert!(e.contains("ends inside a sequence"), "{e}");
    }

    #[test]
    fn fragments_are_skipped_and_other_syntaxes_not_walked() {
        let mut b = meta(EXPLICIT_VR_LE);
        b.extend([0xE0, 0x7F, 0x10, 0x00, b'O', b'B', 0, 0]);
        b.extend(UNDEFINED.to_le_bytes());
        // An empty offset table, then a fragment whose bytes would read
        // as a huge element if taken for a header.
        b.extend([0xFE, 0xFF, 0x00, 0xE0, 0, 0, 0, 0]);
        b.extend([0xFE, 0xFF, 0x00, 0xE0, 8, 0, 0, 0]);
        b.extend([0x09, 0x00, 0x10, 0x00, b'O', b'B', 0, 0]);
        b.extend([0xFE, 0xFF, 0xDD, 0xE0, 0, 0, 0, 0]);
        assert!(transfer_syntax_checked(&b).is_ok());
        let jpeg = "1.2.840.10008.1.2.4.50";
        let mut c = meta(jpeg);
        c.extend([
            0x09, 0x00, 0x10, 0x00, b'O', b'B', 0, 0, 0xFF, 0xFF, 0xFF, 0x00,
        ]);
        assert_eq!(transfer_syntax_checked(&c), Ok(Some(jpeg.to_string())));
        assert_eq!(transfer_syntax_checked(b"not dicom"), Ok(None));
    }
}
