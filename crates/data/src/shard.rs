//! Shards of work for cluster job arrays: `N` tasks each take a
//! contiguous, nearly equal part `K` of one ordered list (a matrix's pairs,
//! a library's references, a calibration's pairs), so that the parts
//! merge into exactly what one machine computes.

/// Shard `index` of `count` (1-based), written `K/N`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Shard {
    /// `K`, from 1 to `count`.
    pub index: usize,
    /// `N`, the number of shards.
    pub count: usize,
}

/// A shard that is not `K/N` with `1 ≤ K ≤ N`.
#[derive(Debug, PartialEq, Eq, thiserror::Error)]
#[error("`{0}`: a shard is K/N with 1 ≤ K ≤ N, e.g. 2/8")]
pub struct ShardSyntax(String);

impl std::fmt::Display for Shard {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}/{}", self.index, self.count)
    }
}

impl std::str::FromStr for Shard {
    type Err = ShardSyntax;

    /// Parse `K/N` with `1 ≤ K ≤ N`.
    fn from_str(s: &str) -> Result<Self, ShardSyntax> {
        let bad = || ShardSyntax(s.to_string());
        let (k, n) = s.split_once('/').ok_or_else(bad)?;
        let index: usize = k.trim().parse().map_err(|_| bad())?;
        let count: usize = n.trim().parse().map_err(|_| bad())?;
        if index == 0 || index > count {
            return Err(bad());
        }
        Ok(Shard { index, count })
    }
}

impl Shard {
    /// The positions `[start, end)` of a list of `total` items that this
    /// shard covers: `start = ⌊(K−1)·total/N⌋`, `end = ⌊K·total/N⌋`. The
    /// `N` ranges are disjoint, cover the list, and differ in length by
    /// at most one.
    pub fn range(&self, total: usize) -> std::ops::Range<usize> {
        let count = self.count.max(1) as u128;
        let at = |k: usize| (k as u128 * total as u128 / count) as usize;
        at(self.index.saturating_sub(1))..at(self.index.min(self.count))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_ranges_of_all_shards_tile_the_list() {
        for total in [0, 1, 7, 100, 101] {
            for count in 1..=9 {
                let mut next = 0;
                for index in 1..=count {
                    let r = Shard { index, count }.range(total);
                    assert_eq!(r.start, next);
                    assert!(r.len() <= total / count + 1);
                    next = r.end;
                }
                assert_eq!(next, total);
            }
        }
        assert!("0/3".parse::<Shard>().is_err());
        assert!("4/3".parse::<Shard>().is_err());
        assert_eq!(
            "2/3".parse::<Shard>().unwrap(),
            Shard { index: 2, count: 3 }
        );
    }
}
