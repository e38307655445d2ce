//! Helpers shared by the text formats: logical lines, tokens, numbers.

use std::io::{self, Write};

/// The logical lines of a text file, numbered from 1, without the line break, a trailing
/// `\r` or a `#` comment; a line ending in `\` continues on the next one (the joined line
/// carries the first line's number).
pub(crate) struct Lines<'a> {
    data: &'a [u8],
    pos: usize,
    line: usize,
    /// The current line: a range of `data`, or `joined` when it was continued.
    current: Option<(usize, usize)>,
    joined: Vec<u8>,
}

impl<'a> Lines<'a> {
    /// Lines of `data`.
    pub(crate) fn new(data: &'a [u8]) -> Self {
        Lines {
            data,
            pos: 0,
            line: 0,
            current: None,
            joined: Vec::new(),
        }
    }

    /// Bytes not yet consumed.
    pub(crate) fn remaining(&self) -> usize {
        self.data.len() - self.pos
    }

    /// Number of the last physical line read.
    pub(crate) fn line(&self) -> usize {
        self.line
    }

    /// The next physical line as a range of `data`, without its comment, break and `\r`.
    fn physical(&mut self) -> Option<(usize, usize)> {
        if self.pos >= self.data.len() {
            return None;
        }
        let start = self.pos;
        let rest = &self.data[start..];
        let len = rest.iter().position(|&b| b == b'\n').unwrap_or(rest.len());
        self.pos += (len + 1).min(rest.len());
        self.line += 1;
        let mut line = &rest[..len];
        if let Some(hash) = line.iter().position(|&b| b == b'#') {
            line = &line[..hash];
        } else if let Some(l) = line.strip_suffix(b"\r") {
            line = l;
        }
        Some((start, start + line.len()))
    }

    /// Moves to the next logical line; returns its number.
    pub(crate) fn advance(&mut self) -> Option<usize> {
        let (start, end) = self.physical()?;
        let number = self.line;
        if !self.data[start..end].ends_with(b"\\") {
            self.current = Some((start, end));
            return Some(number);
        }
        self.current = None;
        self.joined.clear();
        let (mut start, mut end) = (start, end);
        loop {
            let part = &self.data[start..end];
            match part.strip_suffix(b"\\") {
                Some(head) => {
                    self.joined.extend_from_slice(head);
                    self.joined.push(b' ');
                    match self.physical() {
                        Some(next) => (start, end) = next,
                        None => break,
                    }
                }
                None => {
                    self.joined.extend_from_slice(part);
                    break;
                }
            }
        }
        Some(number)
    }

    /// The line [`Lines::advance`] moved to.
    pub(crate) fn current(&self) -> &[u8] {
        match self.current {
            Some((start, end)) => &self.data[start..end],
            None => &self.joined,
        }
    }

    /// The next logical line and its number.
    pub(crate) fn next_line(&mut self) -> Option<(usize, &[u8])> {
        let number = self.advance()?;
        Some((number, self.current()))
    }
}

/// The whitespace-separated tokens of a line.
pub(crate) fn tokens(line: &[u8]) -> impl Iterator<Item = &[u8]> {
    line.split(|b| b.is_ascii_whitespace())
        .filter(|t| !t.is_empty())
}

/// A token as text for messages (lossy for non-UTF-8 bytes, cut to 40 characters).
pub(crate) fn show(token: &[u8]) -> String {
    let s = String::from_utf8_lossy(token);
    if s.chars().count() > 40 {
        format!("{}…", s.chars().take(40).collect::<String>())
    } else {
        s.into_owned()
    }
}

/// A decimal floating-point number (also `inf`/`nan`, which callers reject by name).
#[inline]
pub(crate) fn parse_f64(token: &[u8]) -> Option<f64> {
    std::str::from_utf8(token).ok()?.parse().ok()
}

/// A decimal integer with an optional sign.
#[inline]
pub(crate) fn parse_i64(token: &[u8]) -> Option<i64> {
    let (negative, digits) = match token.first()? {
        b'-' => (true, &token[1..]),
        b'+' => (false, &token[1..]),
        _ => (false, token),
    };
    if digits.is_empty() {
        return None;
    }
    let mut value: i64 = 0;
    for &d in digits {
        if !d.is_ascii_digit() {
            return None;
        }
        value = value.checked_mul(10)?.checked_sub(i64::from(d - b'0'))?;
    }
    // Accumulated negatively so that i64::MIN parses.
    if negative {
        Some(value)
    } else {
        value.checked_neg()
    }
}

/// Name of a non-finite value for messages.
pub(crate) fn non_finite_name(x: f64) -> &'static str {
    if x.is_nan() { "NaN" } else { "infinite" }
}

/// Writes `x` in the shortest decimal form that reads back to the same bits: plain
/// notation for ordinary magnitudes, exponent notation for very large or small ones.
pub(crate) fn write_f64(w: &mut impl Write, x: f64) -> io::Result<()> {
    let a = x.abs();
    if a != 0.0 && !(1e-5..1e16).contains(&a) {
        write!(w, "{x:e}")
    } else {
        write!(w, "{x}")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn all_lines(data: &[u8]) -> Vec<(usize, String)> {
        let mut lines = Lines::new(data);
        let mut out = Vec::new();
        while let Some((n, l)) = lines.next_line() {
            out.push((n, String::from_utf8(l.to_vec()).unwrap()));
        }
        out
    }

    #[test]
    fn lines_strip_comments_crlf_and_join_continuations() {
        let got = all_lines(b"a 1 # note\r\nb 2 \\\n  3\\\n4\n\nc");
        assert_eq!(
            got,
            [
                (1, "a 1 ".to_string()),
                (2, "b 2    3 4".to_string()),
                (5, String::new()),
                (6, "c".to_string())
            ]
        );
    }

    #[test]
    fn continuation_at_end_of_file_ends_the_line() {
        assert_eq!(all_lines(b"f 1 2 3 \\"), [(1, "f 1 2 3  ".to_string())]);
    }

    #[test]
    fn integers_parse_with_sign_and_reject_garbage_and_overflow() {
        assert_eq!(parse_i64(b"42"), Some(42));
        assert_eq!(parse_i64(b"-7"), Some(-7));
        assert_eq!(parse_i64(b"+3"), Some(3));
        assert_eq!(parse_i64(b"-9223372036854775808"), Some(i64::MIN));
        assert_eq!(parse_i64(b"9223372036854775808"), None);
        assert_eq!(parse_i64(b"1a"), None);
        assert_eq!(parse_i64(b"-"), None);
        assert_eq!(parse_i64(b""), None);
    }

    #[test]
    fn floats_are_written_so_that_they_read_back_bit_for_bit() {
        for x in [
            0.1,
            -0.0,
            1.0 / 3.0,
            1e-300,
            -2.5e300,
            123456.789,
            f64::MIN_POSITIVE,
            5e-324,
            f64::MAX,
            1e16,
            9.999e15,
            1e-5,
        ] {
            let mut s = Vec::new();
            write_f64(&mut s, x).unwrap();
            let back = parse_f64(&s).unwrap();
            assert_eq!(
                back.to_bits(),
                x.to_bits(),
                "{}",
                String::from_utf8_lossy(&s)
            );
        }
        let mut s = Vec::new();
        write_f64(&mut s, 1e-300).unwrap();
        assert_eq!(s, b"1e-300");
    }
}
