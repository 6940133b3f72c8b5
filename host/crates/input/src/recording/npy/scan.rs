//! The `.npy` header's dictionary, read by a flat single-pass scanner (no recursion,
//! no evaluation: the work is linear in the header's length).

use super::MAX_RANK;

/// The three keys of a header dictionary.
pub(super) struct Dict {
    pub(super) descr: String,
    pub(super) fortran_order: bool,
    pub(super) shape: Vec<usize>,
}

/// A single-pass scanner over the header text. It never recurses: the only nesting the
/// format has is the shape tuple inside the dictionary, and that is a fixed second
/// level, so nested braces, lists or any other Python value are refused where they
/// start.
pub(super) struct Scanner<'a> {
    text: &'a str,
    pos: usize,
}

impl<'a> Scanner<'a> {
    pub(super) fn new(text: &'a str) -> Self {
        Self { text, pos: 0 }
    }

    fn peek(&self) -> Option<u8> {
        self.text.as_bytes().get(self.pos).copied()
    }

    fn skip_ws(&mut self) {
        while matches!(self.peek(), Some(b' ' | b'\t' | b'\n' | b'\r')) {
            self.pos += 1;
        }
    }

    /// What is at the cursor, for messages (escaped, so a header cannot write to a
    /// terminal).
    fn here(&self) -> String {
        match self.text[self.pos..].chars().next() {
            Some(c) => format!("{:?} at byte {}", c, self.pos),
            None => "the end of the header".to_owned(),
        }
    }

    fn require(&mut self, c: u8) -> Result<(), String> {
        self.skip_ws();
        if self.peek() == Some(c) {
            self.pos += 1;
            Ok(())
        } else {
            Err(format!("expected '{}', found {}", c as char, self.here()))
        }
    }

    /// A quoted string without escapes (numpy never writes any).
    fn string(&mut self) -> Result<&'a str, String> {
        self.skip_ws();
        let quote = match self.peek() {
            Some(q @ (b'\'' | b'"')) => q,
            _ => return Err(format!("expected a quoted string, found {}", self.here())),
        };
        let start = self.pos + 1;
        let len = self.text.as_bytes()[start..]
            .iter()
            .position(|&c| c == quote || c == b'\\')
            .ok_or("unterminated string")?;
        let end = start + len;
        if self.text.as_bytes()[end] == b'\\' {
            return Err(format!("escape sequence at byte {end}"));
        }
        self.pos = end + 1;
        Ok(&self.text[start..end])
    }

    fn word(&mut self) -> &'a str {
        self.skip_ws();
        let start = self.pos;
        while matches!(self.peek(), Some(c) if c.is_ascii_alphanumeric() || c == b'_') {
            self.pos += 1;
        }
        &self.text[start..self.pos]
    }

    fn boolean(&mut self) -> Result<bool, String> {
        let at = self.here();
        match self.word() {
            "True" => Ok(true),
            "False" => Ok(false),
            _ => Err(format!("expected True or False, found {at}")),
        }
    }

    /// A non-negative decimal integer, with Python 2's `L` suffix allowed.
    fn dimension(&mut self) -> Result<usize, String> {
        let at = self.here();
        let w = self.word();
        let digits = w.strip_suffix('L').unwrap_or(w);
        if digits.is_empty() || !digits.bytes().all(|c| c.is_ascii_digit()) {
            return Err(format!("expected a dimension, found {at}"));
        }
        digits
            .parse()
            .map_err(|_| format!("dimension {digits} does not fit in {} bits", usize::BITS))
    }

    /// `(a, b, c)`, `(a,)` or `()`.
    fn shape(&mut self) -> Result<Vec<usize>, String> {
        self.require(b'(')?;
        let mut shape = Vec::new();
        let mut comma = false;
        loop {
            self.skip_ws();
            if self.peek() == Some(b')') {
                self.pos += 1;
                break;
            }
            if shape.len() == MAX_RANK {
                return Err(format!("more than {MAX_RANK} dimensions"));
            }
            shape.push(self.dimension()?);
            self.skip_ws();
            comma = self.peek() == Some(b',');
            match self.peek() {
                Some(b',') => self.pos += 1,
                Some(b')') => {}
                _ => return Err(format!("expected ',' or ')', found {}", self.here())),
            }
        }
        // `(5)` is an integer in Python, not a tuple.
        if shape.len() == 1 && !comma {
            return Err("shape (n) is not a tuple; expected (n,)".to_owned());
        }
        Ok(shape)
    }

    /// `{'descr': ..., 'fortran_order': ..., 'shape': ...}` in any key order, each key
    /// exactly once, a trailing comma allowed, nothing after it but whitespace.
    pub(super) fn dict(mut self) -> Result<Dict, String> {
        self.require(b'{')?;
        let (mut descr, mut fortran, mut shape) = (None, None, None);
        loop {
            self.skip_ws();
            if self.peek() == Some(b'}') {
                self.pos += 1;
                break;
            }
            let key = self.string()?;
            self.require(b':')?;
            let dup = match key {
                "descr" => descr.replace(self.string()?.to_owned()).is_some(),
                "fortran_order" => fortran.replace(self.boolean()?).is_some(),
                "shape" => shape.replace(self.shape()?).is_some(),
                other => return Err(format!("unexpected key {other:?}")),
            };
            if dup {
                return Err(format!("key {key:?} given twice"));
            }
            self.skip_ws();
            match self.peek() {
                Some(b',') => self.pos += 1,
                Some(b'}') => {}
                _ => return Err(format!("expected ',' or '}}', found {}", self.here())),
            }
        }
        self.skip_ws();
        if self.pos != self.text.len() {
            return Err(format!("unexpected {} after the dictionary", self.here()));
        }
        let missing = |k: &str| format!("no {k:?} key");
        Ok(Dict {
            descr: descr.ok_or_else(|| missing("descr"))?,
            fortran_order: fortran.ok_or_else(|| missing("fortran_order"))?,
            shape: shape.ok_or_else(|| missing("shape"))?,
        })
    }
}
