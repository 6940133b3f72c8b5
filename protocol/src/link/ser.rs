//! postcard's wire format, written by a serde serializer whose primitives stay out of
//! line.
//!
//! postcard's own serializer inlines the varint and bounds-check code into every
//! field of every message; for the link's dozens of message variants that is several
//! KB of the firmware's 64 KB flash budget. This one writes the same bytes (the
//! golden tests pin them, and a test compares it with postcard on every message
//! kind) through two small functions, [`Out::put`] and [`Out::var`].

use core::fmt;

use serde::ser::{self, Serialize};

/// The output did not have room, or a value postcard cannot write (a sequence of
/// unknown length).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct Full;

impl fmt::Display for Full {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str("message does not fit")
    }
}

impl core::error::Error for Full {}

impl ser::Error for Full {
    fn custom<T: fmt::Display>(_: T) -> Self {
        Full
    }
}

/// Bytes written into a slice.
pub(crate) struct Out<'a> {
    pub buf: &'a mut [u8],
    pub at: usize,
}

impl Out<'_> {
    #[inline(never)]
    fn put(&mut self, bytes: &[u8]) -> Result<(), Full> {
        let end = self.at + bytes.len();
        self.buf
            .get_mut(self.at..end)
            .ok_or(Full)?
            .copy_from_slice(bytes);
        self.at = end;
        Ok(())
    }

    /// An unsigned LEB128 varint of a value that fits 32 bits (postcard's for u16,
    /// u32 and lengths): the 32-bit path is what the firmware runs.
    #[inline(never)]
    fn var32(&mut self, mut v: u32) -> Result<(), Full> {
        let mut b = [0u8; 5];
        let mut n = 0;
        loop {
            let low = (v & 0x7F) as u8;
            v >>= 7;
            if v == 0 {
                b[n] = low;
                n += 1;
                break;
            }
            b[n] = low | 0x80;
            n += 1;
        }
        self.put(&b[..n])
    }

    /// An unsigned LEB128 varint (postcard's for u64): the low groups of a value
    /// over 32 bits, each with its continuation bit, then the 32-bit path for the
    /// rest.
    fn var(&mut self, mut v: u64) -> Result<(), Full> {
        while v > u64::from(u32::MAX) {
            self.put(&[(v as u8 & 0x7F) | 0x80])?;
            v >>= 7;
        }
        self.var32(v as u32)
    }

    /// A zigzag varint (postcard's for i16, i32, i64).
    fn ivar(&mut self, v: i64) -> Result<(), Full> {
        self.var(((v << 1) ^ (v >> 63)) as u64)
    }
}

/// Writes `value` in postcard's format; returns the bytes used.
pub(crate) fn to_slice<T: Serialize + ?Sized>(value: &T, buf: &mut [u8]) -> Result<usize, Full> {
    let mut out = Out { buf, at: 0 };
    value.serialize(&mut out)?;
    Ok(out.at)
}

/// The variants with fields, tuple or struct: the variant's index, then the fields
/// (written by the compound forms' impls below).
macro_rules! variants_with_fields {
    ($($method:ident),*) => {$(
        fn $method(
            self,
            _: &'static str,
            index: u32,
            _: &'static str,
            _: usize,
        ) -> Result<Self, Full> {
            self.var32(index)?;
            Ok(self)
        }
    )*};
}

impl ser::Serializer for &mut Out<'_> {
    type Ok = ();
    type Error = Full;
    type SerializeSeq = Self;
    type SerializeTuple = Self;
    type SerializeTupleStruct = Self;
    type SerializeTupleVariant = Self;
    type SerializeMap = Self;
    type SerializeStruct = Self;
    type SerializeStructVariant = Self;

    fn is_human_readable(&self) -> bool {
        false
    }
    fn serialize_bool(self, v: bool) -> Result<(), Full> {
        self.put(&[u8::from(v)])
    }
    fn serialize_i8(self, v: i8) -> Result<(), Full> {
        self.put(&[v as u8])
    }
    fn serialize_i16(self, v: i16) -> Result<(), Full> {
        self.var32(((i32::from(v) << 1) ^ (i32::from(v) >> 15)) as u32)
    }
    fn serialize_i32(self, v: i32) -> Result<(), Full> {
        self.var32(((v << 1) ^ (v >> 31)) as u32)
    }
    fn serialize_i64(self, v: i64) -> Result<(), Full> {
        self.ivar(v)
    }
    fn serialize_u8(self, v: u8) -> Result<(), Full> {
        self.put(&[v])
    }
    fn serialize_u16(self, v: u16) -> Result<(), Full> {
        self.var32(u32::from(v))
    }
    fn serialize_u32(self, v: u32) -> Result<(), Full> {
        self.var32(v)
    }
    fn serialize_u64(self, v: u64) -> Result<(), Full> {
        self.var(v)
    }
    fn serialize_f32(self, v: f32) -> Result<(), Full> {
        self.put(&v.to_le_bytes())
    }
    fn serialize_f64(self, v: f64) -> Result<(), Full> {
        self.put(&v.to_le_bytes())
    }
    fn serialize_char(self, v: char) -> Result<(), Full> {
        let mut b = [0u8; 4];
        self.serialize_str(v.encode_utf8(&mut b))
    }
    fn serialize_str(self, v: &str) -> Result<(), Full> {
        self.serialize_bytes(v.as_bytes())
    }
    fn serialize_bytes(self, v: &[u8]) -> Result<(), Full> {
        self.var32(u32::try_from(v.len()).map_err(|_| Full)?)?;
        self.put(v)
    }
    fn serialize_none(self) -> Result<(), Full> {
        self.put(&[0])
    }
    fn serialize_some<T: Serialize + ?Sized>(self, value: &T) -> Result<(), Full> {
        self.put(&[1])?;
        value.serialize(self)
    }
    fn serialize_unit(self) -> Result<(), Full> {
        Ok(())
    }
    fn serialize_unit_struct(self, _: &'static str) -> Result<(), Full> {
        Ok(())
    }
    fn serialize_unit_variant(
        self,
        _: &'static str,
        index: u32,
        _: &'static str,
    ) -> Result<(), Full> {
        self.var32(index)
    }
    fn serialize_newtype_struct<T: Serialize + ?Sized>(
        self,
        _: &'static str,
        value: &T,
    ) -> Result<(), Full> {
        value.serialize(self)
    }
    fn serialize_newtype_variant<T: Serialize + ?Sized>(
        self,
        _: &'static str,
        index: u32,
        _: &'static str,
        value: &T,
    ) -> Result<(), Full> {
        self.var32(index)?;
        value.serialize(self)
    }
    fn serialize_seq(self, len: Option<usize>) -> Result<Self, Full> {
        self.var(len.ok_or(Full)? as u64)?;
        Ok(self)
    }
    fn serialize_tuple(self, _: usize) -> Result<Self, Full> {
        Ok(self)
    }
    fn serialize_tuple_struct(self, _: &'static str, _: usize) -> Result<Self, Full> {
        Ok(self)
    }
    fn serialize_map(self, len: Option<usize>) -> Result<Self, Full> {
        self.var(len.ok_or(Full)? as u64)?;
        Ok(self)
    }
    fn serialize_struct(self, _: &'static str, _: usize) -> Result<Self, Full> {
        Ok(self)
    }
    variants_with_fields!(serialize_tuple_variant, serialize_struct_variant);
    fn collect_str<T: fmt::Display + ?Sized>(self, _: &T) -> Result<(), Full> {
        Err(Full)
    }
}

/// The compound forms: their elements, in order, nothing around them.
macro_rules! elements {
    ($($trait:ident :: $method:ident),*) => {$(
        impl ser::$trait for &mut Out<'_> {
            type Ok = ();
            type Error = Full;
            fn $method<T: Serialize + ?Sized>(&mut self, value: &T) -> Result<(), Full> {
                value.serialize(&mut **self)
            }
            fn end(self) -> Result<(), Full> {
                Ok(())
            }
        }
    )*};
}

elements!(
    SerializeSeq::serialize_element,
    SerializeTuple::serialize_element,
    SerializeTupleStruct::serialize_field,
    SerializeTupleVariant::serialize_field
);

impl ser::SerializeMap for &mut Out<'_> {
    type Ok = ();
    type Error = Full;
    fn serialize_key<T: Serialize + ?Sized>(&mut self, key: &T) -> Result<(), Full> {
        key.serialize(&mut **self)
    }
    fn serialize_value<T: Serialize + ?Sized>(&mut self, value: &T) -> Result<(), Full> {
        value.serialize(&mut **self)
    }
    fn end(self) -> Result<(), Full> {
        Ok(())
    }
}

/// The struct forms: their fields' values, in order, without the names.
macro_rules! fields {
    ($($trait:ident),*) => {$(
        impl ser::$trait for &mut Out<'_> {
            type Ok = ();
            type Error = Full;
            fn serialize_field<T: Serialize + ?Sized>(
                &mut self,
                _: &'static str,
                value: &T,
            ) -> Result<(), Full> {
                value.serialize(&mut **self)
            }
            fn end(self) -> Result<(), Full> {
                Ok(())
            }
        }
    )*};
}

fields!(SerializeStruct, SerializeStructVariant);

#[cfg(test)]
mod tests {
    use super::*;
    use crate::link::*;
    use crate::Limits;

    /// The same bytes as postcard for every message kind and the extremes of every
    /// integer width.
    #[test]
    fn writes_what_postcard_writes() {
        fn same<T: Serialize + core::fmt::Debug>(v: &T) {
            let mut a = [0u8; 400];
            let mut b = [0u8; 400];
            let n = to_slice(v, &mut a).unwrap();
            let want = postcard::to_slice(v, &mut b).unwrap();
            assert_eq!(&a[..n], &want[..], "{v:?}");
        }
        for x in [
            0u64,
            1,
            127,
            128,
            16383,
            16384,
            u64::from(u32::MAX),
            u64::from(u32::MAX) + 1,
            1 << 49,
            u64::MAX,
        ] {
            same(&x);
            same(&(x as u32));
            same(&(x as u16));
            same(&(x as i64));
            same(&(x as i32));
            same(&(x as i16));
            same(&-(x as i64));
            same(&(x as i16).wrapping_neg());
        }
        same(&[i16::MIN, i16::MAX, -1, 0, 1, 300, -300, 5]);
        same(&(
            1u8,
            true,
            -3i8,
            Some(5u32),
            None::<u8>,
            "héllo",
            'x',
            1.5f32,
            -2.5f64,
        ));
        let bytes = [7u8; 200];
        let events = [
            Event::Button(Gesture::Slot(3)),
            Event::LimitHit {
                source: Source::Stream,
                kind: Limit::Thermal,
                channel: 7,
            },
            Event::TooHot {
                source: Source::Slot(1),
                channel: 2,
                permille: 700,
                cooldown_ms: 99_999,
            },
            Event::StreamStopped(StreamStop::Underrun),
        ];
        for e in events {
            same(&Message::Event {
                tick: u32::MAX,
                event: e,
            });
        }
        let replies = [
            Reply::Hello {
                version: 1,
                firmware: "0.1.0",
            },
            Reply::Info(Info {
                link_version: 1,
                firmware: "x",
                layout: "paper-2x4",
                layout_hash: u32::MAX,
                full_scale_ma: 1000,
                limits: Limits::SLEEVE,
                max_message: 288,
                max_chunk: 256,
                bank_capacity: 1 << 18,
                bank: BankState::Builtin(BankSummary {
                    len: 9,
                    crc: 1 << 31,
                    slots: 3,
                }),
            }),
            Reply::Status(StatusReport {
                tick: 5,
                playing: Some(Source::Stream),
                stopping: true,
                selected: 3,
                heat_permille: [1, 200, 3000, 4, 5, 6, 7, 65535],
                cooldown_ms: 1,
                faults: 2,
                last_fault: None,
                upload: Some(77),
            }),
            Reply::BankData {
                offset: 3,
                bytes: &bytes,
            },
            Reply::Play(PlayReply {
                slot: 1,
                tick: 1 << 30,
                now: false,
            }),
            Reply::Stop(StopReply {
                source: None,
                tick: 0,
            }),
            Reply::StreamBegin(StreamBeginReply { capacity: 300 }),
            Reply::StreamEnd,
        ];
        for r in replies {
            same(&Message::Reply {
                seq: 65535,
                reply: r,
            });
        }
        same(&Message::Refused {
            seq: 1,
            error: LinkError::BadCrc {
                expected: 1,
                computed: u32::MAX,
            },
        });
        same(&Message::Unreadable(FrameError::Malformed));
        same(&Request {
            seq: 2,
            command: Command::StreamData {
                index: 9,
                keyframes: &bytes,
            },
        });
        same(&Request {
            seq: 2,
            command: Command::StreamBegin(StreamParams {
                keyframe_period_ms: 1,
                ramp_ms: 2,
                full_scale_ma: 3,
                limits: Limits::SLEEVE,
            }),
        });
        let mut small = [0u8; 3];
        assert_eq!(
            to_slice(
                &Reply::BankData {
                    offset: 0,
                    bytes: &bytes
                },
                &mut small
            ),
            Err(Full)
        );
    }
}
