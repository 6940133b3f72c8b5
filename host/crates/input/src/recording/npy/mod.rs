//! The `.npy` format, read by hand so that the work is bounded by the file.
//!
//! A third-party reader evaluated the header as a Python literal (exponential in nested
//! braces) and allocated whatever the shape claimed before looking at the body. Here the
//! header is read by a flat scanner that knows the three keys numpy writes and refuses
//! everything else, and the shape is checked against the bytes that are really there,
//! with checked arithmetic, before anything is allocated.

use ndarray::{Array3, ShapeBuilder};

use super::RecordingError;

mod scan;

use scan::Scanner;

/// The magic string every `.npy` file starts with.
pub(super) const MAGIC: &[u8; 6] = b"\x93NUMPY";

/// Longest header accepted, in bytes. numpy writes about 128 and refuses more than
/// 10 000 by default when reading; this leaves room for any honest writer while keeping
/// a stream (a `.npz` entry) from making us buffer an unbounded header.
pub(super) const MAX_HEADER_LEN: usize = 1 << 16;

/// Most dimensions accepted in a header (numpy's own limit is 64).
const MAX_RANK: usize = 64;

/// Bytes needed to know where the header ends: magic, version, and the length field.
pub(super) const PREAMBLE_LEN: usize = 12;

/// What kind of number an element is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Kind {
    /// IEEE binary floating point (`f`).
    Float,
    /// Two's-complement signed integer (`i`).
    Int,
    /// Unsigned integer (`u`).
    Uint,
}

/// An element type from the `descr` key: only plain numbers, never records or objects.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(super) struct Dtype {
    /// The descriptor as written, for messages.
    pub descr: String,
    pub kind: Kind,
    /// Bytes per element.
    pub size: usize,
    pub big_endian: bool,
}

/// A parsed header and where the data starts.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(super) struct Header {
    /// `Err(descr)` when `descr` names a type this reader does not convert.
    pub dtype: Result<Dtype, String>,
    pub fortran_order: bool,
    pub shape: Vec<usize>,
    /// Offset of the first data byte from the start of the file.
    pub data_start: usize,
}

impl Header {
    /// Data bytes the shape needs, or `None` if that overflows `u64` or the element
    /// type is one this reader does not know. A zero-length axis needs zero bytes whatever the others say.
    pub(crate) fn data_len(&self) -> Option<u64> {
        let size = self.dtype.as_ref().ok()?.size as u64;
        if self.shape.contains(&0) {
            return Some(0);
        }
        self.shape
            .iter()
            .try_fold(size, |acc, &d| acc.checked_mul(d as u64))
    }

    /// The shape as numpy prints it, `(2, 3)`, for messages.
    pub(crate) fn shape_str(&self) -> String {
        shape_str(&self.shape)
    }
}

/// `(a, b, c)` with numpy's one-element comma.
pub(super) fn shape_str(shape: &[usize]) -> String {
    match shape {
        [one] => format!("({one},)"),
        _ => {
            let parts: Vec<String> = shape.iter().map(usize::to_string).collect();
            format!("({})", parts.join(", "))
        }
    }
}

fn not_npy(name: &str, detail: impl Into<String>) -> RecordingError {
    RecordingError::NotNpy {
        name: name.to_owned(),
        detail: detail.into(),
    }
}

/// Where the header text lies, from the first [`PREAMBLE_LEN`] bytes (or fewer, if the
/// file is shorter): `(start, end)` offsets into the file.
pub(super) fn header_extent(name: &str, bytes: &[u8]) -> Result<(usize, usize), RecordingError> {
    if bytes.len() < MAGIC.len() || &bytes[..MAGIC.len()] != MAGIC {
        return Err(not_npy(name, "missing the \\x93NUMPY magic string"));
    }
    let (major, minor) = match bytes.get(6..8) {
        Some(&[major, minor]) => (major, minor),
        _ => return Err(not_npy(name, "file ends inside the preamble")),
    };
    if !(1..=3).contains(&major) || minor != 0 {
        return Err(not_npy(
            name,
            format!("format version {major}.{minor}; only 1.0, 2.0 and 3.0 exist"),
        ));
    }
    let (start, len) = if major == 1 {
        match bytes.get(8..10) {
            Some(&[a, b]) => (10, usize::from(u16::from_le_bytes([a, b]))),
            _ => return Err(not_npy(name, "file ends inside the preamble")),
        }
    } else {
        match bytes.get(8..12) {
            Some(&[a, b, c, d]) => (12, u32::from_le_bytes([a, b, c, d]) as usize),
            _ => return Err(not_npy(name, "file ends inside the preamble")),
        }
    };
    if len > MAX_HEADER_LEN {
        return Err(not_npy(
            name,
            format!("header of {len} bytes; at most {MAX_HEADER_LEN} are accepted"),
        ));
    }
    Ok((start, start + len))
}

/// Parses the preamble and header of a `.npy` file. `bytes` must hold at least the
/// header (the whole file is fine); the data is not looked at.
pub(super) fn parse_header(name: &str, bytes: &[u8]) -> Result<Header, RecordingError> {
    let (start, end) = header_extent(name, bytes)?;
    let Some(raw) = bytes.get(start..end) else {
        return Err(not_npy(
            name,
            format!(
                "header of {} bytes but the file ends after {}",
                end - start,
                bytes.len().saturating_sub(start)
            ),
        ));
    };
    let text = std::str::from_utf8(raw).map_err(|_| not_npy(name, "header is not text"))?;
    let dict = Scanner::new(text)
        .dict()
        .map_err(|e| not_npy(name, format!("header: {e}")))?;
    Ok(Header {
        dtype: dtype(&dict.descr),
        fortran_order: dict.fortran_order,
        shape: dict.shape,
        data_start: end,
    })
}

/// Checks a header against the recording's contract: float32 or float64, or integers
/// (a sensor's raw counts, which the sanity checks then call such), three dimensions,
/// none of them zero. Returns the shape.
pub(super) fn pressure_shape(name: &str, header: &Header) -> Result<[usize; 3], RecordingError> {
    match &header.dtype {
        Ok(d) if d.kind == Kind::Float && d.size >= 4 => {}
        Ok(d) if matches!(d.kind, Kind::Int | Kind::Uint) => {}
        Ok(Dtype { descr, .. }) | Err(descr) => {
            return Err(RecordingError::UnsupportedDtype {
                name: name.to_owned(),
                descr: descr.clone(),
            })
        }
    }
    let &[t, r, c] = header.shape.as_slice() else {
        return Err(RecordingError::WrongRank {
            name: name.to_owned(),
            ndim: header.shape.len(),
        });
    };
    if t == 0 || r == 0 || c == 0 {
        return Err(RecordingError::Empty {
            name: name.to_owned(),
            shape: [t, r, c],
        });
    }
    Ok([t, r, c])
}

/// Checks a header with [`pressure_shape`] and the bytes that follow it with
/// [`check_len`], then decodes them. Nothing is allocated before both hold, so the
/// allocation is the size of `body`.
pub(super) fn pressure(
    name: &str,
    header: &Header,
    body: &[u8],
) -> Result<Array3<f64>, RecordingError> {
    let [t, r, c] = pressure_shape(name, header)?;
    check_len(name, header, body.len() as u64)?;
    let values = match &header.dtype {
        Ok(dtype) => to_f64(dtype, body),
        Err(_) => Vec::new(),
    };
    Array3::from_shape_vec((t, r, c).set_f(header.fortran_order), values).map_err(|e| {
        RecordingError::NotNpy {
            name: name.to_owned(),
            detail: e.to_string(),
        }
    })
}

/// Refuses `found` data bytes unless they are exactly what the header needs.
pub(super) fn check_len(name: &str, header: &Header, found: u64) -> Result<(), RecordingError> {
    let descr = match &header.dtype {
        Ok(d) => d.descr.clone(),
        Err(descr) => {
            return Err(RecordingError::UnsupportedDtype {
                name: name.to_owned(),
                descr: descr.clone(),
            })
        }
    };
    let needed = header.data_len().ok_or_else(|| RecordingError::TooLarge {
        name: name.to_owned(),
        shape: header.shape.clone(),
        descr: descr.clone(),
    })?;
    let (name, shape) = (name.to_owned(), header.shape.clone());
    match found.cmp(&needed) {
        std::cmp::Ordering::Equal => Ok(()),
        std::cmp::Ordering::Less => Err(RecordingError::Truncated {
            name,
            shape,
            descr,
            needed,
            found,
        }),
        std::cmp::Ordering::Greater => Err(RecordingError::TrailingBytes {
            name,
            shape,
            descr,
            needed,
            found,
        }),
    }
}

/// Reads the `descr` string: `<f8`, `>f4`, `<i2`, `|u1`... Anything else (structured
/// types, strings, objects, complex, long double) is returned as `Err(descr)`.
fn dtype(descr: &str) -> Result<Dtype, String> {
    let b = descr.as_bytes();
    let (order, kind, digits) = match b {
        [order, kind, rest @ ..] if !rest.is_empty() => (*order, *kind, rest),
        _ => return Err(descr.to_owned()),
    };
    let size: usize = std::str::from_utf8(digits)
        .ok()
        .filter(|d| d.bytes().all(|c| c.is_ascii_digit()))
        .and_then(|d| d.parse().ok())
        .ok_or_else(|| descr.to_owned())?;
    let kind = match (kind, size) {
        (b'f', 2 | 4 | 8) => Kind::Float,
        (b'i', 1 | 2 | 4 | 8) => Kind::Int,
        (b'u', 1 | 2 | 4 | 8) => Kind::Uint,
        _ => return Err(descr.to_owned()),
    };
    let big_endian = match (order, size) {
        (b'<', _) => false,
        (b'>', _) => true,
        // Single bytes have no order; numpy writes `|`.
        (b'|', 1) => false,
        _ => return Err(descr.to_owned()),
    };
    Ok(Dtype {
        descr: descr.to_owned(),
        kind,
        size,
        big_endian,
    })
}

/// The elements of `data` as f64 (integers above 2^53 round to the nearest). A partial
/// last element is ignored: the callers have checked the length against the shape.
pub(super) fn to_f64(dtype: &Dtype, data: &[u8]) -> Vec<f64> {
    use rayon::prelude::*;
    // On the rayon pool, written in place in element order (an hour of the paper's
    // sleeve is 12 M elements).
    macro_rules! conv {
        ($n:literal, $decode:expr) => {
            data.par_chunks_exact($n)
                .map(|c| {
                    let mut w = [0u8; $n];
                    w.copy_from_slice(c);
                    if dtype.big_endian {
                        w.reverse();
                    }
                    #[allow(clippy::redundant_closure_call)]
                    $decode(w)
                })
                .collect()
        };
    }
    match (dtype.kind, dtype.size) {
        (Kind::Float, 8) => conv!(8, f64::from_le_bytes),
        (Kind::Float, 4) => conv!(4, |w| f64::from(f32::from_le_bytes(w))),
        (Kind::Float, _) => conv!(2, |w| half_to_f64(u16::from_le_bytes(w))),
        (Kind::Int, 8) => conv!(8, |w| i64::from_le_bytes(w) as f64),
        (Kind::Int, 4) => conv!(4, |w| f64::from(i32::from_le_bytes(w))),
        (Kind::Int, 2) => conv!(2, |w| f64::from(i16::from_le_bytes(w))),
        (Kind::Int, _) => conv!(1, |w| f64::from(i8::from_le_bytes(w))),
        (Kind::Uint, 8) => conv!(8, |w| u64::from_le_bytes(w) as f64),
        (Kind::Uint, 4) => conv!(4, |w| f64::from(u32::from_le_bytes(w))),
        (Kind::Uint, 2) => conv!(2, |w| f64::from(u16::from_le_bytes(w))),
        (Kind::Uint, _) => conv!(1, |w: [u8; 1]| f64::from(w[0])),
    }
}

/// IEEE half precision to f64, exactly.
fn half_to_f64(h: u16) -> f64 {
    let sign = if h & 0x8000 != 0 { -1.0 } else { 1.0 };
    let exp = i32::from((h >> 10) & 0x1f);
    let frac = f64::from(h & 0x3ff);
    sign * match exp {
        0 => frac * 2f64.powi(-24),
        31 if frac == 0.0 => f64::INFINITY,
        31 => f64::NAN,
        _ => (1.0 + frac / 1024.0) * 2f64.powi(exp - 15),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn file(header: &str) -> Vec<u8> {
        let mut v = MAGIC.to_vec();
        v.extend_from_slice(&[1, 0]);
        v.extend_from_slice(&(header.len() as u16).to_le_bytes());
        v.extend_from_slice(header.as_bytes());
        v
    }

    fn parse(header: &str) -> Result<Header, String> {
        parse_header("t.npy", &file(header)).map_err(|e| e.to_string())
    }

    #[test]
    fn reads_what_numpy_writes() {
        let h =
            parse("{'descr': '<f8', 'fortran_order': False, 'shape': (3, 4, 5), }   \n").unwrap();
        assert_eq!(h.shape, [3, 4, 5]);
        assert!(!h.fortran_order);
        assert_eq!(h.dtype.as_ref().unwrap().kind, Kind::Float);
        assert_eq!(h.data_len(), Some(3 * 4 * 5 * 8));
        let h = parse("{\"shape\": (7,), \"fortran_order\": True, \"descr\": \">i2\"}").unwrap();
        assert_eq!((h.shape.as_slice(), h.fortran_order), (&[7][..], true));
        assert!(h.dtype.unwrap().big_endian);
        assert_eq!(
            parse("{'descr':'|u1','fortran_order':False,'shape':()}")
                .unwrap()
                .shape,
            Vec::<usize>::new()
        );
        assert_eq!(
            parse("{'descr':'<f4','fortran_order':False,'shape':(2L, 3L)}")
                .unwrap()
                .shape,
            [2, 3]
        );
    }

    #[test]
    fn refuses_anything_else_in_the_header() {
        for (header, why) in [
            (
                "{'descr': {'descr': '<f8'}, 'fortran_order': False, 'shape': ()}",
                "quoted string",
            ),
            (
                "{'descr': '<f8', 'fortran_order': False, 'shape': ((1,),)}",
                "dimension",
            ),
            (
                "{'descr': '<f8', 'fortran_order': False, 'shape': [1, 2]}",
                "expected '('",
            ),
            (
                "{'descr': '<f8', 'fortran_order': False, 'shape': (5)}",
                "not a tuple",
            ),
            (
                "{'descr': '<f8', 'fortran_order': 0, 'shape': ()}",
                "True or False",
            ),
            ("{'descr': '<f8', 'fortran_order': False}", "no \"shape\""),
            (
                "{'descr': '<f8', 'descr': '<f8', 'fortran_order': False, 'shape': ()}",
                "twice",
            ),
            (
                "{'descr': '<f8', 'fortran_order': False, 'shape': (), 'x': 1}",
                "unexpected key",
            ),
            (
                "{'descr': '<f8', 'fortran_order': False, 'shape': ()} {",
                "after the dictionary",
            ),
            (
                "{'descr': '<\\f8', 'fortran_order': False, 'shape': ()}",
                "escape",
            ),
            (
                "{'descr': '<f8', 'fortran_order': False, 'shape': (-1,)}",
                "dimension",
            ),
            (
                "{'descr': '<f8', 'fortran_order': False, 'shape': (99999999999999999999,)}",
                "does not fit",
            ),
            (
                "{'descr': '<f8', 'fortran_order': False, 'shape': (1,",
                "expected a dimension",
            ),
        ] {
            let e = parse(header).unwrap_err();
            assert!(e.contains("t.npy") && e.contains(why), "{header}: {e}");
        }
    }

    #[test]
    fn nesting_is_refused_at_the_first_level() {
        let header = format!("{}{}", "{".repeat(20), "}".repeat(20));
        let e = parse(&header).unwrap_err();
        assert!(e.contains("'{' at byte 1"), "{e}");
    }

    #[test]
    fn descriptors() {
        assert!(dtype("<f8").is_ok() && dtype(">f4").is_ok() && dtype("|i1").is_ok());
        for d in [
            "<f16", "<c16", "|O", "<U3", "|b1", "f8", "=f8", "|f8", "<f", "<f+8", "<M8[ns]",
        ] {
            assert_eq!(dtype(d), Err(d.to_owned()), "{d}");
        }
    }

    #[test]
    fn conversions_are_exact() {
        let be = Dtype {
            descr: ">f4".into(),
            kind: Kind::Float,
            size: 4,
            big_endian: true,
        };
        assert_eq!(to_f64(&be, &1.5f32.to_be_bytes()), [1.5]);
        let h = Dtype {
            descr: "<f2".into(),
            kind: Kind::Float,
            size: 2,
            big_endian: false,
        };
        // 1.0, -2.5, 65504 (max), the smallest subnormal.
        let halves = [0x3c00u16, 0xc100, 0x7bff, 0x0001];
        let bytes: Vec<u8> = halves.iter().flat_map(|h| h.to_le_bytes()).collect();
        assert_eq!(to_f64(&h, &bytes), [1.0, -2.5, 65504.0, 2f64.powi(-24)]);
        let i = Dtype {
            descr: ">i2".into(),
            kind: Kind::Int,
            size: 2,
            big_endian: true,
        };
        assert_eq!(to_f64(&i, &(-300i16).to_be_bytes()), [-300.0]);
    }
}
