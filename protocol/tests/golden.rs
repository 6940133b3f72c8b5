//! Byte-exact pins of small files: any change to these bytes is a format change
//! and needs a new version number (see SPEC.md).

use touch_protocol::{bank, stimulus, Bank, Error, Stimulus};

/// The pinned files' author: a keyframe every 50 ms, a 20 ms ramp, 4 bits dropped.
fn builder(name: &str) -> stimulus::Builder<'_> {
    stimulus::Builder::new(name, 50)
        .ramp_ms(20)
        .quant_shift(4)
        .layout("t", 0x0403_0201)
}

#[test]
fn stimulus_bytes_are_pinned() {
    let keyframes = [
        [0; 8],
        [1600, 0, 0, 0, 0, 0, 0, -160],
        [3200, 0, 0, 0, 0, 0, 0, -320],
    ];
    let bytes = builder("tap").encode(&keyframes).unwrap();
    #[rustfmt::skip]
    let expected: Vec<u8> = [
        &b"TCHS"[..],                 // magic
        &[0x03, 0x00],                // version 3, u16 LE
        &[48, 0, 0, 0],               // total length, u32 LE
        // postcard header
        &[0x08],                      // channels = 8
        &[0xE8, 0x07],                // output_rate_hz = 1000 (varint)
        &[50],                        // keyframe_period_ms
        &[3],                         // keyframe_count
        &[100],                       // duration_ms = (3 - 1) * 50
        &[20],                        // ramp_ms
        &[0xE8, 0x07],                // full_scale_ma = 1000
        &[4],                         // quant_shift
        &[6],                         // residual_k (codes 199 and 18 in 17 bits, as k = 7 does)
        &[0x01, 0x02, 0x03, 0x04],    // layout_hash, u32 LE (fixed width)
        &[1, b't'],                   // layout name
        &[0xE8, 0x07, 50, 0xD8, 0x04, 0x80, 0x87, 0xA7, 0x0E], // limits 1000, 50, 600, 30e6
        &[3, b't', b'a', b'p'],       // name
        // keyframes, bits:
        //   010        skip 1: keyframe 0 follows its prediction (0); Exp-Golomb of 1
        //   10000001   keyframe 1 changes channels 0 and 7
        //   1110000111 ch0 residual 100: zigzag 200, code 199 = 3 * 64 + 7 (Rice, k = 6)
        //   0010010    ch7 residual -10: zigzag 19, code 18 = 0 * 64 + 18
        //   010        skip 1: keyframe 2 continues both lines (200, -20), the last
        //   0          padding
        &[0b0101_0000, 0b0011_1100, 0b0011_1001, 0b0010_0100],
    ]
    .concat();
    assert_eq!(&bytes[..bytes.len() - 4], &expected[..]);
    let crc = touch_protocol::container::crc32(&expected);
    assert_eq!(&bytes[bytes.len() - 4..], &crc.to_le_bytes());
    assert_eq!(
        crc, 0xD15B_4109,
        "CRC of the pinned bytes (Python zlib.crc32 agrees)"
    );
    let s = Stimulus::decode(&bytes).unwrap();
    assert_eq!(s.name(), "tap");
    assert_eq!(s.keyframes().collect::<Vec<_>>(), keyframes.to_vec());
}

#[test]
fn bank_bytes_are_pinned() {
    let one = builder("a").encode(&[[0; 8]]).unwrap();
    assert_eq!(one.len(), 10 + 27 + 2 + 4);
    let image = bank::encode(&[&one]).unwrap();
    #[rustfmt::skip]
    let prefix: Vec<u8> = [
        &b"TCHB"[..],                 // magic
        &[0x03, 0x00],                // version 3
        &[71, 0, 0, 0],               // total length = 10 + 2 + 4 + 8 + 43 + 4
        &[1, 0],                      // one slot
        &[0x01, 0x02, 0x03, 0x04],    // layout_hash, the stimulus's
        &[24, 0, 0, 0, 43, 0, 0, 0],  // slot 0 at offset 24, 43 bytes
    ]
    .concat();
    assert_eq!(image.len(), 71);
    assert_eq!(&image[..24], &prefix[..24]);
    assert_eq!(&image[24..67], &one[..]);
    let b = Bank::decode(&image).unwrap();
    assert_eq!(b.len(), 1);
    assert_eq!(b.layout_hash(), 0x0403_0201);
    assert_eq!(b.slot(0).unwrap().name(), "a");
    assert_eq!(b.slot(1).unwrap_err(), Error::NoSuchSlot(1));
}

#[test]
fn version_and_crc_errors_say_which() {
    let mut bytes = builder("v").encode(&[[0; 8]]).unwrap();
    // A file of the previous version (byte-coded keyframes) or a future one, with a
    // valid CRC, is "unsupported version"...
    for found in [2, 4] {
        bytes[4] = found as u8;
        let n = bytes.len();
        let crc = touch_protocol::container::crc32(&bytes[..n - 4]);
        bytes[n - 4..].copy_from_slice(&crc.to_le_bytes());
        assert_eq!(
            Stimulus::decode(&bytes).unwrap_err(),
            Error::UnsupportedVersion {
                found,
                supported: 3
            }
        );
    }
    // ...and any flipped bit is "bad CRC".
    bytes[12] ^= 0x10;
    assert!(matches!(
        Stimulus::decode(&bytes),
        Err(Error::BadCrc { .. })
    ));
    // A bank is not a stimulus.
    let one = builder("v").encode(&[[0; 8]]).unwrap();
    let image = bank::encode(&[&one]).unwrap();
    assert!(matches!(
        Stimulus::decode(&image),
        Err(Error::BadMagic { .. })
    ));
}

#[test]
fn a_bank_holds_one_layout_and_says_which() {
    let ours = builder("a").encode(&[[0; 8]]).unwrap();
    let theirs = builder("b")
        .layout("t", 0x0403_0202)
        .encode(&[[0; 8]])
        .unwrap();
    // Building a bank of two layouts is refused with both hashes...
    assert_eq!(
        bank::encode(&[&ours, &theirs]).unwrap_err(),
        Error::WrongLayout {
            found: 0x0403_0202,
            expected: 0x0403_0201
        }
    );
    // ...and so is reading one that was built by hand: patch the bank's hash.
    let mut image = bank::encode(&[&ours]).unwrap();
    image[12] = 0x02;
    let n = image.len();
    let crc = touch_protocol::container::crc32(&image[..n - 4]);
    image[n - 4..].copy_from_slice(&crc.to_le_bytes());
    assert_eq!(
        Bank::decode(&image).unwrap_err(),
        Error::WrongLayout {
            found: 0x0403_0201,
            expected: 0x0403_0202
        }
    );
    let image = bank::encode(&[&ours]).unwrap();
    let b = Bank::decode(&image).unwrap();
    assert_eq!(b.check_layout(0x0403_0201), Ok(()));
    assert!(b.check_layout(touch_protocol::layout::SLEEVE_HASH).is_err());
}
