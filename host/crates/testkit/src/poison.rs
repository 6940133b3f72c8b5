//! Hand-built `.npy` and `.npz` files, most of them wrong in one way that once hung,
//! crashed or aborted the reader, with a zip writer that can lie about sizes (no zip
//! library would write these files, and the reader's own library must not be the
//! oracle for what an archive holds).

use std::io::Write;

/// A version 1.0 `.npy` file: magic, this header text as is, then `body`.
pub fn npy_raw(header: &str, body: &[u8]) -> Vec<u8> {
    let mut v = b"\x93NUMPY\x01\x00".to_vec();
    v.extend_from_slice(&u16::try_from(header.len()).unwrap().to_le_bytes());
    v.extend_from_slice(header.as_bytes());
    v.extend_from_slice(body);
    v
}

/// A `.npy` file as numpy writes it: the dict, padded with spaces and a newline so the
/// data starts on a 64-byte boundary.
pub fn npy(descr: &str, fortran: bool, shape: &str, body: &[u8]) -> Vec<u8> {
    let fortran = if fortran { "True" } else { "False" };
    let mut header =
        format!("{{'descr': '{descr}', 'fortran_order': {fortran}, 'shape': {shape}, }}");
    while (10 + header.len() + 1) % 64 != 0 {
        header.push(' ');
    }
    header.push('\n');
    npy_raw(&header, body)
}

/// Little-endian float64 bytes.
pub fn f64s(values: impl IntoIterator<Item = f64>) -> Vec<u8> {
    values.into_iter().flat_map(f64::to_le_bytes).collect()
}

/// A `[frames, 2, 3]` float64 recording whose every cell is `value`: small, valid.
pub fn small_npy(frames: usize, value: f64) -> Vec<u8> {
    npy(
        "<f8",
        false,
        &format!("({frames}, 2, 3)"),
        &f64s(std::iter::repeat_n(value, frames * 6)),
    )
}

/// A 0-d scalar entry.
pub fn scalar_npy(descr: &str, body: &[u8]) -> Vec<u8> {
    npy(descr, false, "()", body)
}

/// CRC-32 (IEEE), bit by bit: the zip writer below must not share code with the reader.
pub(crate) fn crc32(bytes: &[u8]) -> u32 {
    let mut crc = !0u32;
    for &b in bytes {
        crc ^= u32::from(b);
        for _ in 0..8 {
            crc = if crc & 1 != 0 {
                (crc >> 1) ^ 0xEDB8_8320
            } else {
                crc >> 1
            };
        }
    }
    !crc
}

/// One member of a hand-built archive.
pub struct Entry<'a> {
    /// Its file name in the archive.
    pub name: &'a str,
    /// Its uncompressed bytes.
    pub data: Vec<u8>,
    /// Deflated (else stored).
    pub deflate: bool,
    /// Uncompressed size to write in the headers instead of the true one.
    pub declared: Option<u32>,
}

impl<'a> Entry<'a> {
    /// `data` stored as `name`, its true size in the headers.
    pub fn stored(name: &'a str, data: Vec<u8>) -> Self {
        Self {
            name,
            data,
            deflate: false,
            declared: None,
        }
    }

    /// `data` deflated as `name`, its true size in the headers.
    pub fn deflated(name: &'a str, data: Vec<u8>) -> Self {
        Self {
            deflate: true,
            ..Self::stored(name, data)
        }
    }
}

/// A plain (not zip64) archive: local headers, data, central directory, end record.
pub fn zip(entries: &[Entry<'_>]) -> Vec<u8> {
    let mut out = Vec::new();
    let mut central = Vec::new();
    for e in entries {
        let payload = if e.deflate {
            let mut enc =
                flate2::write::DeflateEncoder::new(Vec::new(), flate2::Compression::best());
            enc.write_all(&e.data).unwrap();
            enc.finish().unwrap()
        } else {
            e.data.clone()
        };
        let method: u16 = if e.deflate { 8 } else { 0 };
        let size = e.declared.unwrap_or(e.data.len() as u32);
        let offset = out.len() as u32;
        let common = |v: &mut Vec<u8>| {
            v.extend_from_slice(&20u16.to_le_bytes()); // version needed
            v.extend_from_slice(&0u16.to_le_bytes()); // flags
            v.extend_from_slice(&method.to_le_bytes());
            v.extend_from_slice(&[0, 0, 0x21, 0]); // time, date (1980-01-01)
            v.extend_from_slice(&crc32(&e.data).to_le_bytes());
            v.extend_from_slice(&(payload.len() as u32).to_le_bytes());
            v.extend_from_slice(&size.to_le_bytes());
            v.extend_from_slice(&(e.name.len() as u16).to_le_bytes());
            v.extend_from_slice(&0u16.to_le_bytes()); // extra length
        };
        out.extend_from_slice(b"PK\x03\x04");
        common(&mut out);
        out.extend_from_slice(e.name.as_bytes());
        out.extend_from_slice(&payload);
        central.extend_from_slice(b"PK\x01\x02");
        central.extend_from_slice(&20u16.to_le_bytes()); // version made by
        common(&mut central);
        central.extend_from_slice(&[0; 6]); // comment length, disk, internal attributes
        central.extend_from_slice(&0u32.to_le_bytes()); // external attributes
        central.extend_from_slice(&offset.to_le_bytes());
        central.extend_from_slice(e.name.as_bytes());
    }
    let cd_offset = out.len() as u32;
    out.extend_from_slice(&central);
    out.extend_from_slice(b"PK\x05\x06");
    out.extend_from_slice(&[0; 4]); // disk numbers
    out.extend_from_slice(&(entries.len() as u16).to_le_bytes());
    out.extend_from_slice(&(entries.len() as u16).to_le_bytes());
    out.extend_from_slice(&(central.len() as u32).to_le_bytes());
    out.extend_from_slice(&cd_offset.to_le_bytes());
    out.extend_from_slice(&0u16.to_le_bytes()); // comment length
    out
}

/// `[6, 2, 3]` ones as a `pressure` entry whose 1 MiB of extra zeros deflate to about 1
/// kB, declaring the size the header needs: a zip bomb that only reading finds.
pub(crate) fn zip_bomb() -> Vec<u8> {
    let mut data = small_npy(6, 1.0);
    let honest = data.len() as u32;
    data.resize(data.len() + (1 << 20), 0);
    zip(&[Entry {
        declared: Some(honest),
        ..Entry::deflated("pressure.npy", data)
    }])
}

/// Files that must each be refused with a clear error: (file name, bytes, a phrase the
/// message must hold).
pub fn poisoned() -> Vec<(&'static str, Vec<u8>, &'static str)> {
    // 126 bytes in all: a 116-byte header of braces nested 20 deep. Evaluating it as a
    // Python literal took exponential time.
    let nested = {
        let mut h = format!("{}{}", "{".repeat(20), "}".repeat(20));
        while h.len() < 115 {
            h.push(' ');
        }
        h.push('\n');
        npy_raw(&h, &[])
    };
    assert_eq!(nested.len(), 126);
    let max = u64::MAX;
    let body = f64s((0..200).map(f64::from));
    vec![
        ("nested.npy", nested, "'{' at byte 1"),
        (
            // Panicked inside the third-party reader.
            "huge_dims.npy",
            npy("<f8", false, &format!("(0, {max}, {max})"), &[]),
            "empty recording",
        ),
        (
            "overflow.npy",
            npy("<f8", false, &format!("(5, {max}, {max})"), &[0; 64]),
            "overflows 64 bits",
        ),
        (
            // Aborted on a 134 GB allocation.
            "huge_alloc.npy",
            npy("<f8", false, "(100000000, 8, 21)", &[0; 64]),
            "needs 134400000000 bytes of data, the file holds 64",
        ),
        (
            "truncated.npy",
            npy("<f8", false, "(50, 2, 2)", &body[..1592]),
            "truncated",
        ),
        (
            "trailing.npy",
            npy(
                "<f8",
                false,
                "(50, 2, 2)",
                &[&body[..1600], &[0; 8]].concat(),
            ),
            "8 unexpected bytes after the data",
        ),
        (
            "complex.npy",
            npy("<c8", false, "(50, 2, 2)", &body[..1600]),
            "unsupported element type <c8",
        ),
        (
            "rank2.npy",
            npy("<f8", false, "(50, 4)", &body[..1600]),
            "found 2 dimension",
        ),
        (
            "rank4.npy",
            npy("<f8", false, "(25, 2, 2, 2)", &body[..1600]),
            "found 4 dimension",
        ),
        ("bomb.npz", zip_bomb(), "decompresses to more than"),
        (
            "liar.npz",
            zip(&[Entry {
                declared: Some(u32::MAX),
                ..Entry::deflated("pressure.npy", small_npy(6, 1.0))
            }]),
            "declares 4294967295 bytes",
        ),
        (
            "nopressure.npz",
            zip(&[Entry::stored("psi.npy", small_npy(6, 1.0))]),
            "no array named 'pressure'",
        ),
    ]
}
