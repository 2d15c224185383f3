//! Distance matrices, labels and leave-one-out classification.

pub mod heatmap;
pub mod labels;
pub mod loo;
pub mod mantel;
pub mod matrix;
pub mod shard;

pub use labels::{Labels, LabelsError};
pub use loo::{leave_one_out, RankScore};
pub use mantel::{mantel_r, mantel_test, Mantel, MantelError};
pub use matrix::{distance_matrix, pairwise_matrix, DistanceMatrix, MatrixError};

/// Split one CSV line into fields (RFC 4180 quoting: `"a, b"` and `""`).
pub(crate) fn split_csv_line(line: &str) -> Result<Vec<String>, &'static str> {
    let mut out = Vec::new();
    let mut cur = String::new();
    let mut chars = line.trim_end_matches(['\r', '\n']).chars().peekable();
    let mut quoted = false;
    let mut at_start = true;
    while let Some(ch) = chars.next() {
        if quoted {
            if ch == '"' {
                if chars.peek() == Some(&'"') {
                    cur.push('"');
                    chars.next();
                } else {
                    quoted = false;
                }
            } else {
                cur.push(ch);
            }
        } else if ch == '"' && at_start {
            quoted = true;
            at_start = false;
        } else if ch == ',' {
            out.push(std::mem::take(&mut cur));
            at_start = true;
        } else {
            cur.push(ch);
            at_start = false;
        }
    }
    if quoted {
        return Err("unterminated quoted field");
    }
    out.push(cur);
    Ok(out)
}

/// Quote a CSV field when it needs it.
pub(crate) fn csv_field(s: &str) -> String {
    if s.contains([',', '"', '\n', '\r']) {
        format!("\"{}\"", s.replace('"', "\"\""))
    } else {
        s.to_string()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn splits_quoted_fields() {
        let f = split_csv_line("B03,Primates,NA,\"Plesiadapiform, proto\",\"a\"\"b\"\r\n").unwrap();
        assert_eq!(
            f,
            vec!["B03", "Primates", "NA", "Plesiadapiform, proto", "a\"b"]
        );
        assert!(split_csv_line("a,\"b").is_err());
        assert_eq!(split_csv_line(&csv_field("x,\"y")).unwrap(), vec!["x,\"y"]);
    }
}
