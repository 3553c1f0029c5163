//! Splits one G-code line into its command and words: comments (`;` and `( )`), line
//! numbers and checksums stripped, letters upper-cased, Klipper's extended commands
//! (`SET_PIN PIN=x VALUE=1`) kept as name and parameters. Numbers are parsed only when
//! asked for (`Words::get`), so a message after `M117` never fails. Meaning is `modal`'s.

use super::error::GcodeInError;

/// Longest line read, bytes: slicers write lines under 100 bytes but embed settings
/// dumps of a few KiB in comments; a longer line is not G-code.
pub const MAX_LINE_BYTES: usize = 64 * 1024;

/// A command word.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Code<'a> {
    /// `G<n>` (or `G<n>.<m>`: `sub` is then Some).
    G(u32, Option<u32>),
    /// `M<n>`.
    M(u32, Option<u32>),
    /// `T<n>`.
    T(u32),
    /// A Klipper-style extended command, upper-cased name.
    Ext(&'a str),
    /// Anything else with a first word (kept for the skip count).
    Other(&'a str),
}

/// One line, lexed.
#[derive(Clone, Debug, PartialEq)]
pub struct Line<'a> {
    /// The command, if the line has one.
    pub code: Option<Code<'a>>,
    /// The text after the command word, comments removed.
    pub rest: &'a str,
    /// The `;` comment, without the `;` and leading blanks.
    pub comment: Option<&'a str>,
}

/// Lexes `text` (one line, no newline). `line` is its 1-based number for errors.
pub fn lex(text: &str, line: usize) -> Result<Line<'_>, GcodeInError> {
    if text.len() > MAX_LINE_BYTES {
        return Err(GcodeInError::LineTooLong {
            line,
            len: text.len(),
            limit: MAX_LINE_BYTES,
        });
    }
    let (code_part, comment) = match text.find(';') {
        Some(i) => (&text[..i], Some(text[i + 1..].trim())),
        None => (text, None),
    };
    // A checksum ends the command part.
    let code_part = code_part.split('*').next().unwrap_or("");
    let mut s = code_part.trim_start();
    // Parenthesised comments are only skipped at the start (a line number before them is
    // handled below); words inside them elsewhere are blanked by `Words`.
    let mut code = None;
    // Line number `N123` first.
    if let Some(t) = s.strip_prefix(['N', 'n']) {
        if t.starts_with(|c: char| c.is_ascii_digit()) {
            let end = t.find(|c: char| !c.is_ascii_digit()).unwrap_or(t.len());
            s = t[end..].trim_start();
        }
    }
    while let Some(t) = s.strip_prefix('(') {
        s = t.find(')').map_or("", |i| t[i + 1..].trim_start());
    }
    let mut rest = "";
    if let Some(first) = s.chars().next() {
        let second = s[first.len_utf8()..].chars().next();
        let is_ext = first.is_ascii_alphabetic()
            && second.is_some_and(|c| c.is_ascii_alphabetic() || c == '_');
        if is_ext {
            let end = s.find(char::is_whitespace).unwrap_or(s.len());
            code = Some(Code::Ext(&s[..end]));
            rest = &s[end..];
        } else if first.is_ascii_alphabetic() {
            let t = &s[1..];
            let t = t.trim_start();
            let end = t
                .find(|c: char| !(c.is_ascii_digit() || c == '.'))
                .unwrap_or(t.len());
            let num = &t[..end];
            rest = &t[end..];
            let mut parts = num.splitn(2, '.');
            let major = parts.next().and_then(|p| p.parse::<u32>().ok());
            let minor = parts.next().map(|p| p.parse::<u32>().ok());
            code = Some(match (first.to_ascii_uppercase(), major, minor) {
                ('G', Some(n), None) => Code::G(n, None),
                ('G', Some(n), Some(Some(m))) => Code::G(n, Some(m)),
                ('M', Some(n), None) => Code::M(n, None),
                ('M', Some(n), Some(Some(m))) => Code::M(n, Some(m)),
                ('T', Some(n), None) => Code::T(n),
                _ => Code::Other(s.split_whitespace().next().unwrap_or(s)),
            });
        } else {
            code = Some(Code::Other(s.split_whitespace().next().unwrap_or(s)));
        }
    }
    Ok(Line {
        code,
        rest,
        comment,
    })
}

/// The words after a command: `X10.5 Y-3 E.2`, spaces optional (`X10Y5`).
#[derive(Clone, Copy, Debug)]
pub struct Words<'a> {
    rest: &'a str,
    line: usize,
}

impl<'a> Words<'a> {
    /// The words of `rest` (from [`Line::rest`]) on line `line`.
    pub fn new(rest: &'a str, line: usize) -> Self {
        Words { rest, line }
    }

    /// The value of word `letter` (upper case), if present: a finite decimal number.
    pub fn get(&self, letter: char) -> Result<Option<f64>, GcodeInError> {
        let b = self.rest.as_bytes();
        let mut i = 0;
        let mut depth = 0u32;
        while i < b.len() {
            let c = b[i];
            if c == b'(' {
                depth += 1;
            } else if c == b')' {
                depth = depth.saturating_sub(1);
            } else if depth == 0 && c.is_ascii_alphabetic() {
                let start = i + 1;
                let mut j = start;
                while j < b.len() && b[j] == b' ' {
                    j += 1;
                }
                let vstart = j;
                while j < b.len() && (b[j].is_ascii_digit() || matches!(b[j], b'+' | b'-' | b'.')) {
                    j += 1;
                }
                if c.to_ascii_uppercase() as char == letter {
                    return self.value(letter, &self.rest[vstart..j], &self.rest[vstart..]);
                }
                i = j.max(start);
                continue;
            }
            i += 1;
        }
        Ok(None)
    }

    fn value(&self, letter: char, num: &str, tail: &str) -> Result<Option<f64>, GcodeInError> {
        let line = self.line;
        if num.is_empty() {
            let t = tail.trim_start().to_ascii_lowercase();
            if t.starts_with("nan") || t.starts_with("inf") {
                return Err(GcodeInError::NotFinite { line, letter });
            }
            // A bare letter (`G1 X Y5`) where a value is needed.
            return Err(GcodeInError::BadNumber {
                line,
                letter,
                word: tail.split_whitespace().next().unwrap_or("").to_string(),
            });
        }
        match num.parse::<f64>() {
            Ok(v) if v.is_finite() => Ok(Some(v)),
            Ok(_) => Err(GcodeInError::NotFinite { line, letter }),
            Err(_) => Err(GcodeInError::BadNumber {
                line,
                letter,
                word: num.to_string(),
            }),
        }
    }

    /// Whether word `letter` is present at all (with or without a value).
    pub fn has(&self, letter: char) -> bool {
        let mut depth = 0u32;
        self.rest.bytes().any(|c| {
            if c == b'(' {
                depth += 1;
            } else if c == b')' {
                depth = depth.saturating_sub(1);
            }
            depth == 0 && c.to_ascii_uppercase() as char == letter
        })
    }

    /// Klipper-style `KEY=VALUE` parameter (key upper-cased), raw text.
    pub fn param(&self, key: &str) -> Option<&'a str> {
        self.rest.split_whitespace().find_map(|kv| {
            let (k, v) = kv.split_once('=')?;
            k.eq_ignore_ascii_case(key).then_some(v)
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn commands_words_and_comments() {
        let l = lex("N12 G1 X10.5Y-3 E.25 ; perimeter", 1).unwrap();
        assert_eq!(l.code, Some(Code::G(1, None)));
        assert_eq!(l.comment, Some("perimeter"));
        let w = Words::new(l.rest, 1);
        assert_eq!(w.get('X').unwrap(), Some(10.5));
        assert_eq!(w.get('Y').unwrap(), Some(-3.0));
        assert_eq!(w.get('E').unwrap(), Some(0.25));
        assert_eq!(w.get('Z').unwrap(), None);
        let k = lex("SET_PIN PIN=dollop_valve1 VALUE=1", 2).unwrap();
        assert_eq!(k.code, Some(Code::Ext("SET_PIN")));
        assert_eq!(Words::new(k.rest, 2).param("pin"), Some("dollop_valve1"));
        assert_eq!(lex("T1", 3).unwrap().code, Some(Code::T(1)));
        assert_eq!(lex("G29.1", 3).unwrap().code, Some(Code::G(29, Some(1))));
        assert_eq!(lex(";TYPE:Wipe tower", 4).unwrap().code, None);
    }

    #[test]
    fn non_finite_and_malformed_numbers_are_typed_errors() {
        let l = lex("G1 X nan", 5).unwrap();
        assert_eq!(
            Words::new(l.rest, 5).get('X'),
            Err(GcodeInError::NotFinite {
                line: 5,
                letter: 'X'
            })
        );
        let big = format!("G1 X1{}", "0".repeat(400));
        let l = lex(&big, 6).unwrap();
        assert!(matches!(
            Words::new(l.rest, 6).get('X'),
            Err(GcodeInError::NotFinite { .. })
        ));
        let l = lex("G1 X1.2.3", 7).unwrap();
        assert!(matches!(
            Words::new(l.rest, 7).get('X'),
            Err(GcodeInError::BadNumber { .. })
        ));
        let long = "G1".to_string() + &" ".repeat(MAX_LINE_BYTES);
        assert!(matches!(
            lex(&long, 8),
            Err(GcodeInError::LineTooLong { .. })
        ));
    }
}
