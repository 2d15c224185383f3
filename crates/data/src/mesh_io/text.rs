//! A whitespace tokenizer over ASCII mesh data that tracks line numbers.

use super::{ParseError, ParseResult};

/// Tokens of an ASCII body, with optional `#` comments to the end of a line.
pub(crate) struct Tokens<'a> {
    data: &'a [u8],
    pos: usize,
    /// Line of the current position (1-based).
    cursor_line: usize,
    /// Line of the token returned last.
    token_line: usize,
    comments: bool,
}

impl<'a> Tokens<'a> {
    /// Tokens of `data`, whose first byte is on line `first_line`.
    pub(crate) fn new(data: &'a [u8], first_line: usize, comments: bool) -> Self {
        Tokens {
            data,
            pos: 0,
            cursor_line: first_line,
            token_line: first_line,
            comments,
        }
    }

    /// Bytes not consumed yet.
    pub(crate) fn remaining(&self) -> usize {
        self.data.len().saturating_sub(self.pos)
    }

    /// Line of the token returned last (for messages).
    pub(crate) fn line(&self) -> usize {
        self.token_line
    }

    /// The next token, or `None` at the end of the data.
    pub(crate) fn next_token(&mut self) -> Option<&'a str> {
        loop {
            let &b = self.data.get(self.pos)?;
            if b == b'\n' {
                self.cursor_line += 1;
                self.pos += 1;
            } else if b.is_ascii_whitespace() {
                self.pos += 1;
            } else if self.comments && b == b'#' {
                self.skip_line();
            } else {
                break;
            }
        }
        let start = self.pos;
        while self
            .data
            .get(self.pos)
            .is_some_and(|b| !(b.is_ascii_whitespace() || self.comments && *b == b'#'))
        {
            self.pos += 1;
        }
        self.token_line = self.cursor_line;
        // Non-UTF-8 bytes make a token that no number parse accepts.
        Some(std::str::from_utf8(&self.data[start..self.pos]).unwrap_or("\u{fffd}"))
    }

    /// Skip the rest of the current line (including its newline).
    pub(crate) fn skip_line(&mut self) {
        while let Some(&b) = self.data.get(self.pos) {
            self.pos += 1;
            if b == b'\n' {
                self.cursor_line += 1;
                return;
            }
        }
    }

    /// The next token, or an error saying what was expected.
    pub(crate) fn expect(&mut self, what: &str) -> ParseResult<&'a str> {
        match self.next_token() {
            Some(t) => Ok(t),
            None => Err(ParseError::UnexpectedEnd {
                line: self.cursor_line,
                expected: what.to_string(),
            }),
        }
    }

    /// The next token as a number.
    pub(crate) fn expect_f64(&mut self, what: &str) -> ParseResult<f64> {
        let t = self.expect(what)?;
        parse_f64(t).ok_or_else(|| ParseError::Expected {
            line: self.token_line,
            expected: what.to_string(),
            found: shorten(t),
        })
    }

    /// The next token as a non-negative integer.
    pub(crate) fn expect_u64(&mut self, what: &str) -> ParseResult<u64> {
        let t = self.expect(what)?;
        t.parse::<u64>().map_err(|_| ParseError::ExpectedInteger {
            line: self.token_line,
            expected: what.to_string(),
            found: shorten(t),
        })
    }
}

/// Parse a decimal number; unlike `str::parse` this refuses the spellings
/// of infinity and NaN, which no mesh coordinate may take.
pub(crate) fn parse_f64(t: &str) -> Option<f64> {
    t.parse::<f64>().ok().filter(|v| v.is_finite())
}

/// A token cut to a readable length for an error message.
pub(crate) fn shorten(t: &str) -> String {
    let mut s: String = t.chars().take(40).collect();
    if t.chars().count() > 40 {
        s.push('…');
    }
    s.chars()
        .map(|c| if c.is_control() { '?' } else { c })
        .collect()
}
