//! The scan filters of `GET /api/v1/scans` and of the overview page, from
//! the query string: `status`, a taxon at any rank (`genus=Ateles`, or
//! `rank=genus&taxon=Ateles` as the form sends it), `no_close_match`,
//! `reviewed`, `since`/`until` (a UTC day `YYYY-MM-DD`, `until` included,
//! or Unix milliseconds, `until` excluded), `name` (a piece of the file
//! path), and paging: `limit`, `offset`, `cursor` (the `next_cursor` of
//! the page before). Empty values are ignored (a form sends every field);
//! an unknown key or a bad value is refused, naming it.

use super::error::ApiError;
use crate::store::{ScanQuery, ScanStatus};

/// Scans on a page unless `limit` says otherwise.
pub(super) const DEFAULT_LIMIT: usize = 50;

/// The largest `limit`.
pub(super) const MAX_LIMIT: usize = 500;

/// The keys of the filters and paging (any other is a rank's name).
const KEYS: [&str; 11] = [
    "status",
    "rank",
    "taxon",
    "no_close_match",
    "reviewed",
    "since",
    "until",
    "name",
    "limit",
    "offset",
    "cursor",
];

/// Milliseconds in a day.
const DAY_MS: i64 = 86_400_000;

/// The filters of `raw` (a query string). `ranks` are the library's
/// ranks, which may be used as keys (empty: any other key is taken as a
/// rank); `extra` are keys the caller reads itself.
pub(super) fn scan_query(
    raw: Option<&str>,
    ranks: &[String],
    extra: &[&str],
) -> Result<ScanQuery, ApiError> {
    let pairs: Vec<(String, String)> = serde_urlencoded::from_str(raw.unwrap_or(""))
        .map_err(|e| ApiError::BadRequest(format!("malformed query string: {e}")))?;
    let mut q = ScanQuery {
        limit: DEFAULT_LIMIT,
        ..ScanQuery::default()
    };
    let (mut rank, mut taxon) = (None, None);
    for (key, value) in pairs {
        let value = value.trim().to_string();
        if value.is_empty() || extra.contains(&key.as_str()) {
            continue;
        }
        let bad = |why: &str| ApiError::BadRequest(format!("{key}={value:?}: {why}"));
        match key.as_str() {
            "status" => {
                q.status = Some(ScanStatus::parse(&value).ok_or_else(|| {
                    bad("a status is pending, running, ok, error, duplicate or superseded")
                })?)
            }
            "rank" => rank = Some(known_rank(&value, ranks).map_err(|w| bad(&w.to_string()))?),
            "taxon" => taxon = Some(value.clone()),
            "no_close_match" => {
                q.no_close_match = Some(flag(&value).ok_or_else(|| bad("true or false"))?)
            }
            "reviewed" => q.reviewed = Some(flag(&value).ok_or_else(|| bad("true or false"))?),
            "since" => q.since_ms = Some(time_ms(&value, false).ok_or_else(|| bad(TIME))?),
            "until" => q.until_ms = Some(time_ms(&value, true).ok_or_else(|| bad(TIME))?),
            "name" => {
                if value.chars().count() > 200 {
                    return Err(bad("at most 200 characters"));
                }
                q.name = Some(value.clone())
            }
            "limit" => {
                q.limit = value
                    .parse()
                    .ok()
                    .filter(|n| (1..=MAX_LIMIT).contains(n))
                    .ok_or_else(|| bad(&format!("a number from 1 to {MAX_LIMIT}")))?
            }
            "offset" => {
                q.offset = value
                    .parse()
                    .ok()
                    .filter(|n| *n <= 10_000_000)
                    .ok_or_else(|| bad("a number from 0 to 10000000"))?
            }
            "cursor" => {
                q.before_id = Some(
                    value
                        .parse()
                        .map_err(|_| bad("the next_cursor of a page"))?,
                )
            }
            other => {
                let rank = known_rank(other, ranks).map_err(|_| {
                    ApiError::BadRequest(format!(
                        "unknown query parameter {other:?} (filters: {}, or a rank: {})",
                        KEYS.join(", "),
                        ranks.join(", ")
                    ))
                })?;
                q.taxa.push((rank, value.clone()));
            }
        }
    }
    match (rank, taxon) {
        (Some(r), Some(t)) => q.taxa.push((r, t)),
        (None, Some(_)) => return Err(ApiError::BadRequest("taxon= needs rank=".into())),
        _ => {}
    }
    Ok(q)
}

/// What a time value may be.
const TIME: &str = "a UTC day YYYY-MM-DD or Unix milliseconds";

/// Why a name is not a rank a filter takes.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
enum RankError<'a> {
    /// Not a plain name (letters, digits, `_`, `-`; at most 64 bytes), or
    /// the key of another filter.
    #[error("{0:?} is not a rank")]
    NotAName(&'a str),
    /// A plain name, but not one of the library's ranks (which it lists).
    #[error("not a rank of the library ({})", .0.join(", "))]
    NotInLibrary(&'a [String]),
}

/// `name` if it is one of `ranks` (or any plain name when `ranks` is
/// empty).
fn known_rank<'a>(name: &'a str, ranks: &'a [String]) -> Result<String, RankError<'a>> {
    let plain = !name.is_empty()
        && name.len() <= 64
        && name
            .chars()
            .all(|c| c.is_alphanumeric() || c == '_' || c == '-');
    if !plain || KEYS.contains(&name) {
        return Err(RankError::NotAName(name));
    }
    if ranks.is_empty() || ranks.iter().any(|r| r == name) {
        Ok(name.to_string())
    } else {
        Err(RankError::NotInLibrary(ranks))
    }
}

/// `true`/`false` (or 1/0).
fn flag(v: &str) -> Option<bool> {
    match v {
        "true" | "1" => Some(true),
        "false" | "0" => Some(false),
        _ => None,
    }
}

/// A time bound in Unix milliseconds: digits as they are, or a UTC day's
/// start (`end`: the next day's start, so the day is included).
fn time_ms(v: &str, end: bool) -> Option<i64> {
    if v.bytes().all(|b| b.is_ascii_digit()) {
        return v.parse().ok();
    }
    let mut parts = v.splitn(3, '-');
    let (y, m, d) = (parts.next()?, parts.next()?, parts.next()?);
    if y.len() != 4 || m.len() != 2 || d.len() != 2 {
        return None;
    }
    let (y, m, d): (i64, i64, i64) = (y.parse().ok()?, m.parse().ok()?, d.parse().ok()?);
    if !(1..=12).contains(&m) || !(1..=days_in_month(y, m)).contains(&d) {
        return None;
    }
    let start = days_from_civil(y, m, d) * DAY_MS;
    Some(if end { start + DAY_MS } else { start })
}

/// Days in month `m` of year `y` (proleptic Gregorian).
fn days_in_month(y: i64, m: i64) -> i64 {
    match m {
        2 if (y % 4 == 0 && y % 100 != 0) || y % 400 == 0 => 29,
        2 => 28,
        4 | 6 | 9 | 11 => 30,
        _ => 31,
    }
}

/// Days from 1970-01-01 to a civil date (Howard Hinnant's algorithm, the
/// inverse of the reports' `utc_time`).
fn days_from_civil(y: i64, m: i64, d: i64) -> i64 {
    let y = if m <= 2 { y - 1 } else { y };
    let era = y.div_euclid(400);
    let yoe = y - era * 400;
    let mp = (m + 9) % 12;
    let doy = (153 * mp + 2) / 5 + d - 1;
    let doe = yoe * 365 + yoe / 4 - yoe / 100 + doy;
    era * 146_097 + doe - 719_468
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::report::utc_time;

    #[test]
    fn days_round_trip_through_the_reports_clock() {
        for (day, text) in [
            ("1970-01-01", "1970-01-01 00:00:00 UTC"),
            ("2024-02-29", "2024-02-29 00:00:00 UTC"),
        ] {
            let ms = time_ms(day, false).unwrap();
            assert_eq!(utc_time(ms), text);
            assert_eq!(time_ms(day, true).unwrap() - ms, DAY_MS);
        }
        assert_eq!(time_ms("2023-02-29", false), None);
        assert_eq!(time_ms("2023-13-01", false), None);
        assert_eq!(time_ms("1700000000000", false), Some(1_700_000_000_000));
    }

    #[test]
    fn filters_are_read_and_unknown_keys_refused() {
        let ranks = vec!["order".to_string(), "genus".to_string()];
        let q = scan_query(
            Some("status=ok&genus=Ateles&rank=order&taxon=Primates&name=&limit=5&no_close_match=true"),
            &ranks,
            &[],
        )
        .unwrap();
        assert_eq!(q.status, Some(ScanStatus::Ok));
        assert_eq!(
            q.taxa,
            [
                ("genus".into(), "Ateles".into()),
                ("order".into(), "Primates".into())
            ]
        );
        assert_eq!((q.limit, q.no_close_match, q.name), (5, Some(true), None));
        for bad in [
            "family=X",
            "status=done",
            "limit=0",
            "limit=501",
            "since=yesterday",
            "taxon=X",
        ] {
            assert!(
                matches!(
                    scan_query(Some(bad), &ranks, &[]),
                    Err(ApiError::BadRequest(_))
                ),
                "{bad}"
            );
        }
        assert!(scan_query(Some("view=rows"), &ranks, &["view"]).is_ok());
    }

    #[test]
    fn a_refused_rank_says_why() {
        let ranks = vec!["order".to_string(), "genus".to_string()];
        let refusal = |raw| match scan_query(Some(raw), &ranks, &[]) {
            Err(ApiError::BadRequest(why)) => why,
            other => panic!("{raw}: {other:?}"),
        };
        assert_eq!(
            refusal("rank=family"),
            "rank=\"family\": not a rank of the library (order, genus)"
        );
        assert_eq!(refusal("rank=a+b"), "rank=\"a b\": \"a b\" is not a rank");
        assert_eq!(
            refusal("rank=limit"),
            "rank=\"limit\": \"limit\" is not a rank"
        );
        assert_eq!(
            refusal("family=X"),
            "unknown query parameter \"family\" (filters: status, rank, taxon, \
             no_close_match, reviewed, since, until, name, limit, offset, cursor, or a rank: \
             order, genus)"
        );
    }
}
