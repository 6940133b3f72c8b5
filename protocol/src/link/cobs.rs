//! COBS (Consistent Overhead Byte Stuffing): frames without a zero byte inside, so a
//! single `0x00` ends each frame and a receiver that joins mid-stream, or meets
//! garbage, finds the next frame at the next zero.
//!
//! A frame of `n` bytes is stuffed into at most `n + n / 254 + 1` bytes: the data is
//! cut at every zero byte (and after 254 non-zero bytes), and each piece is written
//! as one code byte (`1 +` its length) followed by its bytes; a code of `0xFF` says
//! the piece ended without a zero. The zero that ends a frame on the wire is not
//! part of the encoding.

/// Why stuffed bytes do not decode.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum CobsError {
    /// A zero byte inside the stuffed bytes, or a code that runs past their end.
    Malformed,
    /// The output buffer is too small.
    Overflow,
}

/// Most bytes [`encode`] writes for `n` bytes of data (without the terminating zero).
pub const fn max_encoded_len(n: usize) -> usize {
    n + n / 254 + 1
}

/// Stuffs `data` into `out`; returns the number of bytes written (no zero among
/// them, no terminating zero).
///
/// ```
/// use touch_protocol::link::cobs;
/// let mut out = [0u8; 8];
/// let n = cobs::encode(&[0x11, 0x00, 0x22], &mut out).unwrap();
/// assert_eq!(&out[..n], &[0x02, 0x11, 0x02, 0x22]);
/// ```
pub fn encode(data: &[u8], out: &mut [u8]) -> Result<usize, CobsError> {
    if out.len() < max_encoded_len(data.len()) {
        return Err(CobsError::Overflow);
    }
    let mut code_at = 0;
    let mut w = 1;
    let mut code = 1u8;
    for &b in data {
        if b == 0 {
            out[code_at] = code;
            code_at = w;
            w += 1;
            code = 1;
        } else {
            out[w] = b;
            w += 1;
            code += 1;
            if code == 0xFF {
                out[code_at] = code;
                code_at = w;
                w += 1;
                code = 1;
            }
        }
    }
    out[code_at] = code;
    Ok(w)
}

/// Unstuffs `bytes` (one frame, without its terminating zero) into `out`; returns the
/// length of the data. `out` may be as long as `bytes` (the data is never longer).
///
/// ```
/// use touch_protocol::link::cobs;
/// let mut out = [0u8; 8];
/// let n = cobs::decode(&[0x02, 0x11, 0x02, 0x22], &mut out).unwrap();
/// assert_eq!(&out[..n], &[0x11, 0x00, 0x22]);
/// ```
pub fn decode(bytes: &[u8], out: &mut [u8]) -> Result<usize, CobsError> {
    let mut r = 0;
    let mut w = 0;
    while r < bytes.len() {
        let code = bytes[r];
        if code == 0 {
            return Err(CobsError::Malformed);
        }
        let n = usize::from(code) - 1;
        let end = r + 1 + n;
        if end > bytes.len() {
            return Err(CobsError::Malformed);
        }
        let piece = &bytes[r + 1..end];
        if piece.contains(&0) {
            return Err(CobsError::Malformed);
        }
        if w + n > out.len() {
            return Err(CobsError::Overflow);
        }
        out[w..w + n].copy_from_slice(piece);
        w += n;
        r = end;
        // A piece shorter than 254 bytes ended at a zero, unless it is the last.
        if code != 0xFF && r < bytes.len() {
            if w >= out.len() {
                return Err(CobsError::Overflow);
            }
            out[w] = 0;
            w += 1;
        }
    }
    Ok(w)
}

/// What one byte fed to a [`Decoder`] completed.
#[derive(Debug, PartialEq, Eq)]
pub enum Feed<'a> {
    /// The frame is not complete yet (or an empty frame, `00 00`, was skipped).
    Pending,
    /// A whole frame, unstuffed.
    Frame(&'a [u8]),
    /// The bytes since the last zero did not form a frame: longer than the buffer,
    /// or not valid COBS. They are dropped; the decoder is in step again at the zero
    /// that ended them.
    Dropped(CobsError),
}

/// A streaming frame decoder with room for `N` stuffed bytes per frame.
///
/// Bytes go in one at a time (from a UART interrupt or a USB packet); a zero ends a
/// frame. After garbage, a frame that is too long or a receiver that joined
/// mid-frame, the next zero puts it back in step: only the frame in which the damage
/// happened is lost.
#[derive(Debug, Clone)]
pub struct Decoder<const N: usize> {
    buf: [u8; N],
    len: usize,
    overflow: bool,
}

impl<const N: usize> Default for Decoder<N> {
    fn default() -> Self {
        Self::new()
    }
}

impl<const N: usize> Decoder<N> {
    /// An empty decoder, waiting for the first byte of a frame.
    pub const fn new() -> Self {
        Decoder {
            buf: [0; N],
            len: 0,
            overflow: false,
        }
    }

    /// Forgets a partial frame.
    pub fn reset(&mut self) {
        self.len = 0;
        self.overflow = false;
    }

    /// Bytes of the frame in progress (0 between frames).
    pub fn pending(&self) -> usize {
        self.len
    }

    /// Feeds one byte from the wire.
    pub fn feed(&mut self, byte: u8) -> Feed<'_> {
        if byte != 0 {
            if self.len < N {
                self.buf[self.len] = byte;
                self.len += 1;
            } else {
                self.overflow = true;
            }
            return Feed::Pending;
        }
        let (len, overflow) = (self.len, self.overflow);
        self.reset();
        if overflow {
            return Feed::Dropped(CobsError::Overflow);
        }
        if len == 0 {
            return Feed::Pending;
        }
        // Unstuffing in place is safe: the write position never passes the read one.
        match decode_in_place(&mut self.buf[..len]) {
            Ok(n) => Feed::Frame(&self.buf[..n]),
            Err(e) => Feed::Dropped(e),
        }
    }
}

/// [`decode`] with the output over the input.
fn decode_in_place(buf: &mut [u8]) -> Result<usize, CobsError> {
    let mut r = 0;
    let mut w = 0;
    while r < buf.len() {
        let code = buf[r];
        if code == 0 {
            return Err(CobsError::Malformed);
        }
        let n = usize::from(code) - 1;
        let end = r + 1 + n;
        if end > buf.len() {
            return Err(CobsError::Malformed);
        }
        // Forward, byte by byte: the write position never passes the read one. (Not
        // `copy_within`: it links a 1.5 KB memmove into the firmware for this alone.)
        for i in 0..n {
            buf[w + i] = buf[r + 1 + i];
        }
        w += n;
        r = end;
        if code != 0xFF && r < buf.len() {
            buf[w] = 0;
            w += 1;
        }
    }
    Ok(w)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn round_trip(data: &[u8]) {
        let mut enc = vec![0u8; max_encoded_len(data.len())];
        let n = encode(data, &mut enc).unwrap();
        assert!(!enc[..n].contains(&0), "{data:?}");
        let mut dec = vec![0u8; n];
        let m = decode(&enc[..n], &mut dec).unwrap();
        assert_eq!(&dec[..m], data);
        let mut d = Decoder::<1024>::new();
        for &b in &enc[..n] {
            assert_eq!(d.feed(b), Feed::Pending);
        }
        if data.is_empty() {
            // `01 00`: one code byte, an empty frame.
            assert_eq!(d.feed(0), Feed::Frame(&[]));
        } else {
            assert_eq!(d.feed(0), Feed::Frame(data));
        }
    }

    #[test]
    fn known_encodings() {
        let cases: [(&[u8], &[u8]); 5] = [
            (&[], &[0x01]),
            (&[0x00], &[0x01, 0x01]),
            (&[0x00, 0x00], &[0x01, 0x01, 0x01]),
            (&[0x11, 0x22, 0x00, 0x33], &[0x03, 0x11, 0x22, 0x02, 0x33]),
            (&[0x11, 0x00, 0x00, 0x00], &[0x02, 0x11, 0x01, 0x01, 0x01]),
        ];
        for (data, stuffed) in cases {
            let mut out = [0u8; 16];
            let n = encode(data, &mut out).unwrap();
            assert_eq!(&out[..n], stuffed, "{data:02x?}");
            round_trip(data);
        }
    }

    #[test]
    fn long_runs_without_zero() {
        for len in [253, 254, 255, 508, 509, 600] {
            let data: Vec<u8> = (0..len).map(|i| (i % 255 + 1) as u8).collect();
            round_trip(&data);
            let mut with_zeros = data.clone();
            with_zeros[len / 2] = 0;
            round_trip(&with_zeros);
        }
        // 254 non-zero bytes: one full piece, then an empty last one.
        let data = [7u8; 254];
        let mut out = [0u8; 300];
        let n = encode(&data, &mut out).unwrap();
        assert_eq!((n, out[0], out[255]), (256, 0xFF, 0x01));
    }

    #[test]
    fn decoder_resyncs_after_garbage_and_overflow() {
        let mut d = Decoder::<8>::new();
        // Garbage that is not COBS (a code past the end), then a good frame.
        for &b in &[0x09, 0x01] {
            d.feed(b);
        }
        assert_eq!(d.feed(0), Feed::Dropped(CobsError::Malformed));
        for &b in &[0x02, 0x41] {
            assert_eq!(d.feed(b), Feed::Pending);
        }
        assert_eq!(d.feed(0), Feed::Frame(&[0x41]));
        // Too long for the buffer: dropped at the zero, the next frame is whole.
        for _ in 0..20 {
            d.feed(0x05);
        }
        assert_eq!(d.feed(0), Feed::Dropped(CobsError::Overflow));
        d.feed(0x01);
        assert_eq!(d.feed(0), Feed::Frame(&[]));
        // Zeros between frames are skipped.
        assert_eq!(d.feed(0), Feed::Pending);
    }

    #[test]
    fn decode_refuses_bad_input() {
        let mut out = [0u8; 8];
        assert_eq!(decode(&[0x03, 0x11], &mut out), Err(CobsError::Malformed));
        assert_eq!(decode(&[0x02, 0x00], &mut out), Err(CobsError::Malformed));
        assert_eq!(decode(&[0x00], &mut out), Err(CobsError::Malformed));
        assert_eq!(
            decode(&[0x05, 1, 2, 3, 4], &mut [0u8; 2]),
            Err(CobsError::Overflow)
        );
        assert_eq!(encode(&[1, 2, 3], &mut [0u8; 3]), Err(CobsError::Overflow));
    }
}
