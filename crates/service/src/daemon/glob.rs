//! File-name patterns of `watch.ignore`: `*` (any run of characters), `?`
//! (one character), everything else literal. Matched against the file name
//! only, so `*.part` skips `a/b/x.part`.

/// Whether `name` matches the glob `pattern`.
fn glob_match(pattern: &str, name: &str) -> bool {
    let p: Vec<char> = pattern.chars().collect();
    let n: Vec<char> = name.chars().collect();
    // Iterative matcher with one backtrack point for the last `*`.
    let (mut pi, mut ni) = (0usize, 0usize);
    let mut star: Option<(usize, usize)> = None;
    while ni < n.len() {
        match p.get(pi) {
            Some('*') => {
                star = Some((pi, ni));
                pi += 1;
            }
            Some(&c) if c == '?' || c == n[ni] => {
                pi += 1;
                ni += 1;
            }
            _ => match star {
                Some((sp, sn)) => {
                    pi = sp + 1;
                    ni = sn + 1;
                    star = Some((sp, sn + 1));
                }
                None => return false,
            },
        }
    }
    p[pi.min(p.len())..].iter().all(|&c| c == '*')
}

/// Whether a file name matches any of the patterns.
pub(super) fn is_ignored(patterns: &[String], name: &str) -> bool {
    patterns.iter().any(|p| glob_match(p, name))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn globs_match_names() {
        assert!(glob_match("*.part", "x.part"));
        assert!(!glob_match("*.part", "x.ply"));
        assert!(!glob_match("*.part", "x.part.ply"));
        assert!(glob_match(".*", ".hidden"));
        assert!(!glob_match(".*", "visible"));
        assert!(glob_match("scan?.ply", "scan1.ply"));
        assert!(!glob_match("scan?.ply", "scan12.ply"));
        assert!(glob_match("*a*b*", "xxaybz"));
        assert!(!glob_match("*a*b", "xxaybz"));
        assert!(glob_match("*", ""));
        assert!(!glob_match("?", ""));
        assert!(is_ignored(&["*.tmp".into(), "*.part".into()], "a.tmp"));
    }
}
