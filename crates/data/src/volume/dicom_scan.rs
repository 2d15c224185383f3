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

/// Why the framing of a DICOM file is refused: a length that runs past
/// the end or splits a binary value, a deflated data set that cannot be
/// inflated within bounds, or framing the walk cannot follow.
#[derive(Debug, thiserror::Error)]
pub enum DicomFramingError {
    /// The deflated data set cannot be inflated.
    #[error("the deflated data set cannot be inflated: {0}")]
    Inflate(#[source] std::io::Error),
    /// The deflated data set inflates to more than `limit` bytes.
    #[error("the deflated data set inflates to more than {limit} bytes")]
    InflatesTooFar {
        /// The largest inflated data set taken (bytes).
        limit: u64,
    },
    /// An element of a binary VR whose length is not a whole number of
    /// values.
    #[error(
        "element ({:04X},{:04X}) at byte {at} of VR {vr} holds {len} bytes, not a whole number \
         of {value_size}-byte values (corrupt file)",
        .tag.0,
        .tag.1
    )]
    PartialValue {
        /// The element's tag.
        tag: Tag,
        /// Where its header starts in the file (bytes).
        at: usize,
        /// Its value representation.
        vr: VR,
        /// Its declared value length (bytes).
        len: u32,
        /// The size of one value of the VR (bytes).
        value_size: u32,
    },
    /// An element whose value runs past the end of the data.
    #[error(
        "element ({:04X},{:04X}) at byte {at} declares {len} bytes, but only {left} follow \
         (truncated or corrupt file)",
        .tag.0,
        .tag.1
    )]
    PastTheEnd {
        /// The element's tag.
        tag: Tag,
        /// Where its header starts in the file (bytes).
        at: usize,
        /// Its declared value length (bytes).
        len: u32,
        /// The bytes left after its header.
        left: usize,
    },
    /// The data set's framing cannot be followed.
    #[error("the data set's framing is broken at byte {at}: {why} (corrupt or truncated file)")]
    Broken {
        /// Where in the file (bytes).
        at: usize,
        /// What breaks the framing there.
        why: BrokenFraming,
    },
}

/// What breaks a data set's framing where the walk cannot follow it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum BrokenFraming {
    /// A sequence or item ends at byte `end` of the file, before the
    /// current position.
    EndsBefore {
        /// Where the sequence or item ends in the file (bytes).
        end: usize,
    },
    /// The data ends inside a sequence.
    EndsInSequence,
    /// The data ends inside an element header.
    EndsInHeader,
    /// A pixel data fragment of undefined length.
    UndefinedFragment,
    /// An element where an item belongs.
    NotAnItem {
        /// The element's tag.
        tag: Tag,
    },
}

impl std::fmt::Display for BrokenFraming {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            BrokenFraming::EndsBefore { end } => {
                write!(f, "a sequence or item ends at byte {end}, before it")
            }
            BrokenFraming::EndsInSequence => {
                f.write_str("the data ends inside a sequence (truncated file)")
            }
            BrokenFraming::EndsInHeader => {
                f.write_str("the data ends inside an element header (truncated file)")
            }
            BrokenFraming::UndefinedFragment => {
                f.write_str("a pixel data fragment of undefined length")
            }
            BrokenFraming::NotAnItem { tag } => {
                write!(f, "({:04X},{:04X}) where an item belongs", tag.0, tag.1)
            }
        }
    }
}

/// Walk the framing of the DICOM file `bytes`: its transfer syntax when
/// the file meta group can be read (the data set is walked only for the
/// syntaxes the reader takes), `None` when it cannot (the parser reports
/// why), or what is wrong when a length runs past the end.
#[cfg(test)]
fn transfer_syntax_checked(bytes: &[u8]) -> Result<Option<String>, DicomFramingError> {
    Ok(data_set_checked(bytes)?.map(|d| d.syntax))
}

/// The data set of the DICOM file `bytes` with its framing walked: the
/// transfer syntax when the file meta group can be read (the data set is
/// walked only for the syntaxes the reader takes), `None` when it cannot,
/// or what is wrong when a length runs past the end or the framing cannot
/// be followed.
pub(crate) fn data_set_checked(bytes: &[u8]) -> Result<Option<DataSet<'_>>, DicomFramingError> {
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
            let inflated = inflate(rest)?;
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

/// The deflated data set `rest` inflated, refused past `MAX_INFLATED`.
fn inflate(rest: &[u8]) -> Result<Vec<u8>, DicomFramingError> {
    let mut inflated = Vec::new();
    flate2::read::DeflateDecoder::new(rest)
        .take(MAX_INFLATED + 1)
        .read_to_end(&mut inflated)
        .map_err(DicomFramingError::Inflate)?;
    if inflated.len() as u64 > MAX_INFLATED {
        return Err(DicomFramingError::InflatesTooFar {
            limit: MAX_INFLATED,
        });
    }
    Ok(inflated)
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
fn check(h: &Header, at: usize, total: usize, offset: usize) -> Result<(), DicomFramingError> {
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
        return Err(DicomFramingError::PartialValue {
            tag: h.tag,
            at: offset + at - h.size,
            vr: h.vr,
            len: h.len,
            value_size: size,
        });
    }
    if h.len as usize > left {
        return Err(DicomFramingError::PastTheEnd {
            tag: h.tag,
            at: offset + at - h.size,
            len: h.len,
            left,
        });
    }
    Ok(())
}

/// The file meta group from `start` as the parser reads it (explicit VR,
/// its length from (0002,0000)): the transfer syntax and where the data
/// set starts, or `None` where the parser would fail.
fn meta_group(b: &[u8], start: usize) -> Result<Option<(String, usize)>, DicomFramingError> {
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

/// The error for framing broken at byte `at` (of the file) by `why`.
fn broken(at: usize, why: BrokenFraming) -> DicomFramingError {
    DicomFramingError::Broken { at, why }
}

/// Where a sequence or item of length `len` whose content starts at `at`
/// ends; `None` for an undefined length.
fn end_of(at: usize, len: u32) -> Option<usize> {
    (len != UNDEFINED).then(|| at.saturating_add(len as usize))
}

/// The walk of a data set: the bytes, where they are in the file, how
/// headers are encoded, and the walk's position and state.
struct Walk<'a> {
    /// The data set.
    b: &'a [u8],
    /// Where `b` starts in the file (for messages).
    offset: usize,
    /// Whether headers are explicit VR.
    explicit: bool,
    /// What is open around the current position, innermost last.
    open: Vec<Open>,
    /// The current position in `b`.
    at: usize,
    /// Where the top-level pixel data element starts, once seen.
    pixel_data: Option<usize>,
    /// Whether an item header (or the sequence's end) comes next.
    in_sequence: bool,
}

/// Walk the data set `b` (at byte `offset` of the file, for messages) as
/// the parser's state machine does: element headers and values; after a
/// sequence header, item headers; items hold elements, except those of
/// encapsulated pixel data, which hold bytes. A sequence or item of
/// defined length ends where its length says.
fn data_set(b: &[u8], offset: usize, explicit: bool) -> Result<Option<usize>, DicomFramingError> {
    let mut walk = Walk {
        b,
        offset,
        explicit,
        open: Vec::new(),
        at: 0,
        pixel_data: None,
        in_sequence: false,
    };
    loop {
        walk.close_ended()?;
        if walk.in_sequence {
            walk.sequence_entry()?;
            continue;
        }
        let Some(h) = walk.header() else {
            return walk.end();
        };
        walk.element(&h);
        walk.value_of(&h)?;
    }
}

impl Walk<'_> {
    /// The element header at the current position, in the data set's
    /// encoding.
    fn header(&self) -> Option<Header> {
        if self.explicit {
            explicit_header(self.b, self.at)
        } else {
            implicit_header(self.b, self.at)
        }
    }

    /// Close the sequences and items that end at the current position;
    /// error if one ended before it.
    fn close_ended(&mut self) -> Result<(), DicomFramingError> {
        while let Some(&top) = self.open.last() {
            let (end, item) = match top {
                Open::Sequence { end, .. } => (end, false),
                Open::Item { end } => (end, true),
            };
            match end {
                Some(e) if e == self.at => {
                    self.open.pop();
                    self.in_sequence = item;
                }
                Some(e) if e < self.at => {
                    return Err(broken(
                        self.offset + self.at,
                        BrokenFraming::EndsBefore {
                            end: self.offset + e,
                        },
                    ))
                }
                _ => break,
            }
        }
        Ok(())
    }

    /// Read the header inside a sequence: an item (entered, or skipped
    /// with its bytes for a pixel data fragment), an item's end or the
    /// sequence's end; anything else breaks the framing.
    fn sequence_entry(&mut self) -> Result<(), DicomFramingError> {
        let (b, at) = (self.b, self.at);
        let (Some(group), Some(element), Some(len)) =
            (u16_at(b, at), u16_at(b, at + 2), u32_at(b, at + 4))
        else {
            return Err(broken(self.offset + at, BrokenFraming::EndsInSequence));
        };
        self.at += 8;
        match (group, element) {
            (0xFFFE, 0xE000) => {
                let fragments = matches!(
                    self.open.last(),
                    Some(Open::Sequence {
                        fragments: true,
                        ..
                    })
                );
                if fragments {
                    self.skip_fragment(len)?;
                } else {
                    self.in_sequence = false;
                    self.open.push(Open::Item {
                        end: end_of(self.at, len),
                    });
                }
            }
            (0xFFFE, 0xE00D) => {
                self.open.pop();
            }
            (0xFFFE, 0xE0DD) => {
                self.open.pop();
                self.in_sequence = false;
            }
            _ => {
                return Err(broken(
                    self.offset + self.at - 8,
                    BrokenFraming::NotAnItem {
                        tag: Tag(group, element),
                    },
                ))
            }
        }
        Ok(())
    }

    /// Skip the pixel data fragment of `len` bytes whose item header
    /// ends at the current position, its length checked.
    fn skip_fragment(&mut self, len: u32) -> Result<(), DicomFramingError> {
        if len == UNDEFINED {
            return Err(broken(
                self.offset + self.at - 8,
                BrokenFraming::UndefinedFragment,
            ));
        }
        let h = Header {
            tag: Tag(0xFFFE, 0xE000),
            vr: VR::OB,
            len,
            size: 8,
        };
        check(&h, self.at, self.b.len(), self.offset)?;
        self.at += len as usize;
        Ok(())
    }

    /// Where the data ends without a header: the pixel data's position
    /// when nothing is open and no byte is left, else why the framing is
    /// broken.
    fn end(&self) -> Result<Option<usize>, DicomFramingError> {
        if self.at == self.b.len() && self.open.is_empty() {
            return Ok(self.pixel_data);
        }
        let why = if self.open.is_empty() {
            BrokenFraming::EndsInHeader
        } else {
            BrokenFraming::EndsInSequence
        };
        Err(broken(self.offset + self.at, why))
    }

    /// Note the element of header `h` at the current position (the first
    /// top-level pixel data) and step over its header.
    fn element(&mut self, h: &Header) {
        if h.tag == Tag(0x7FE0, 0x0010) && self.open.is_empty() && self.pixel_data.is_none() {
            self.pixel_data = Some(self.at);
        }
        self.at += h.size;
    }

    /// Enter or step over the value of the element of header `h`, whose
    /// header ends at the current position: a sequence (or an element of
    /// undefined length, read as one) is opened, an item's end closes
    /// the item, any other value is checked and skipped.
    fn value_of(&mut self, h: &Header) -> Result<(), DicomFramingError> {
        if h.vr == VR::SQ {
            self.open.push(Open::Sequence {
                fragments: false,
                end: end_of(self.at, h.len),
            });
            self.in_sequence = true;
        } else if h.tag == Tag(0xFFFE, 0xE00D) {
            // An item's end; ignored outside any sequence.
            if self.open.pop().is_some() {
                self.in_sequence = true;
            }
        } else if h.len == UNDEFINED {
            // Encapsulated pixel data holds fragments; any other element
            // of undefined length is read as a sequence of items.
            self.open.push(Open::Sequence {
                fragments: h.tag == Tag(0x7FE0, 0x0010),
                end: None,
            });
            self.in_sequence = true;
        } else {
            check(h, self.at, self.b.len(), self.offset)?;
            self.at += h.len as usize;
        }
        Ok(())
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
            transfer_syntax_checked(&b).unwrap(),
            Some(EXPLICIT_VR_LE.to_string())
        );
        b.extend([0x09, 0x00, 0x10, 0x00, b'O', b'B', 0, 0]);
        b.extend(0xFFFF_FFFEu32.to_le_bytes());
        b.extend([0u8; 16]);
        let e = transfer_syntax_checked(&b).unwrap_err().to_string();
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
        let e = transfer_syntax_checked(&b).unwrap_err().to_string();
        assert!(e.contains("(0008,1150)") && e.contains("1000000"), "{e}");
    }

    #[test]
    fn binary_values_must_be_whole() {
        // A group length (UL) of 2 bytes: the parser would read no value
        // and go on two bytes out of step.
        let mut b = meta(IMPLICIT_VR_LE);
        b.extend([0x28, 0x00, 0x00, 0x00, 2, 0, 0, 0, 1, 2]);
        let e = transfer_syntax_checked(&b).unwrap_err().to_string();
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
        let e = transfer_syntax_checked(&b).unwrap_err().to_string();
        assert!(e.contains("(0028,0010) where an item belongs"), "{e}");
        // A data set that stops inside an element header.
        let mut c = meta(EXPLICIT_VR_LE);
        c.extend([0x28, 0x00, 0x10, 0x00, b'U']);
        let e = transfer_syntax_checked(&c).unwrap_err().to_string();
        assert!(e.contains("inside an element header"), "{e}");
        // A sequence left open at the end.
        let mut d = meta(EXPLICIT_VR_LE);
        d.extend([0x08, 0x00, 0x40, 0x11, b'S', b'Q', 0, 0]);
        d.extend(UNDEFINED.to_le_bytes());
        let e = transfer_syntax_checked(&d).unwrap_err().to_string();
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
        assert_eq!(transfer_syntax_checked(&c).unwrap(), Some(jpeg.to_string()));
        assert_eq!(transfer_syntax_checked(b"not dicom").unwrap(), None);
    }

    #[test]
    fn errors_carry_their_data_and_read_as_before() {
        let mut b = meta(EXPLICIT_VR_LE);
        b.extend([0x09, 0x00, 0x10, 0x00, b'O', b'B', 0, 0]);
        b.extend(0xFFFF_FFFEu32.to_le_bytes());
        b.extend([0u8; 16]);
        let e = transfer_syntax_checked(&b).unwrap_err();
        assert!(
            matches!(
                e,
                DicomFramingError::PastTheEnd {
                    tag: Tag(0x0009, 0x0010),
                    len: 0xFFFF_FFFE,
                    left: 16,
                    ..
                }
            ),
            "{e:?}"
        );
        let tag = Tag(0x0028, 0x0010);
        let cases = [
            (
                DicomFramingError::Inflate(std::io::Error::other("bad")),
                "the deflated data set cannot be inflated: bad".to_string(),
            ),
            (
                DicomFramingError::InflatesTooFar {
                    limit: MAX_INFLATED,
                },
                format!("the deflated data set inflates to more than {MAX_INFLATED} bytes"),
            ),
            (
                DicomFramingError::PartialValue {
                    tag,
                    at: 10,
                    vr: VR::UL,
                    len: 2,
                    value_size: 4,
                },
                "element (0028,0010) at byte 10 of VR UL holds 2 bytes, not a whole number \
                 of 4-byte values (corrupt file)"
                    .to_string(),
            ),
            (
                DicomFramingError::PastTheEnd {
                    tag,
                    at: 10,
                    len: 99,
                    left: 3,
                },
                "element (0028,0010) at byte 10 declares 99 bytes, but only 3 follow \
                 (truncated or corrupt file)"
                    .to_string(),
            ),
        ];
        for (e, text) in cases {
            assert_eq!(e.to_string(), text);
        }
        let framing = |why: &str| {
            format!("the data set's framing is broken at byte 7: {why} (corrupt or truncated file)")
        };
        for (why, text) in [
            (
                BrokenFraming::EndsBefore { end: 5 },
                "a sequence or item ends at byte 5, before it",
            ),
            (
                BrokenFraming::EndsInSequence,
                "the data ends inside a sequence (truncated file)",
            ),
            (
                BrokenFraming::EndsInHeader,
                "the data ends inside an element header (truncated file)",
            ),
            (
                BrokenFraming::UndefinedFragment,
                "a pixel data fragment of undefined length",
            ),
            (
                BrokenFraming::NotAnItem { tag },
                "(0028,0010) where an item belongs",
            ),
        ] {
            assert_eq!(broken(7, why).to_string(), framing(text));
        }
    }
}
