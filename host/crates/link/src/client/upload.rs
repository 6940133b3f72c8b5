//! The bank region: read it, upload an image to it, check it after the restart.

use std::time::Duration;

use touch_protocol::link::{BankState, Command, LinkError, Reply};

use super::{Client, ClientError, Progress, VerifyError, RETRIES};
use crate::Transport;

/// How long a restarting device is left alone before [`Client::reconnect`] asks.
const RESTART_GRACE: Duration = Duration::from_millis(100);

/// How often [`Client::reconnect`] asks a restarting device (a reply needs a few ms;
/// the boot's bank check up to some 100 ms).
const RESTART_POLL: Duration = Duration::from_millis(50);

/// An upload the device no longer knows (`NoUpload` after its `BankBegin` was
/// answered) was lost to a restart.
fn lost_upload(e: ClientError) -> ClientError {
    match e {
        ClientError::Refused {
            command,
            error: LinkError::NoUpload,
        } => ClientError::Restarted { command },
        e => e,
    }
}

impl<T: Transport> Client<T> {
    /// Reads `len` bytes of the bank region from `offset`.
    pub fn read_bank(
        &mut self,
        offset: u32,
        len: u32,
        mut progress: impl FnMut(Progress),
    ) -> Result<Vec<u8>, ClientError> {
        let chunk = self.chunk_len()?;
        let mut out = Vec::with_capacity(len as usize);
        while (out.len() as u32) < len {
            let at = offset + out.len() as u32;
            let want = (len - out.len() as u32).min(chunk as u32) as u16;
            let timeout = self.timeouts.reply;
            let bytes = self.call(
                Command::BankRead {
                    offset: at,
                    len: want,
                },
                timeout,
                RETRIES,
                |r| match r {
                    Reply::BankData { offset, bytes } if offset == at => Some(bytes.to_vec()),
                    _ => None,
                },
            )?;
            if bytes.is_empty() {
                return Err(ClientError::Protocol("a bank read returned no bytes"));
            }
            out.extend_from_slice(&bytes[..bytes.len().min(want as usize)]);
            progress(Progress {
                done: out.len() as u64,
                total: u64::from(len),
            });
        }
        Ok(out)
    }

    /// Uploads a bank image: erase, chunks, commit. The device checks the image
    /// (length, CRC, format, layout) at the commit and then restarts into it; call
    /// [`Client::verify`] once it is back. A cut anywhere leaves the old bank or
    /// none, never part of this one (the device's rule).
    pub fn upload(
        &mut self,
        image: &[u8],
        mut progress: impl FnMut(Progress),
    ) -> Result<u8, ClientError> {
        let len =
            u32::try_from(image.len()).map_err(|_| ClientError::Protocol("image too long"))?;
        let crc = touch_protocol::container::crc32(image);
        let chunk = self.chunk_len()?;
        let erase = self.timeouts.erase;
        self.call_watched(Command::BankBegin { len, crc }, erase, |r| match r {
            Reply::BankBegin { len: l } if l == len => Some(()),
            _ => None,
        })?;
        let total = u64::from(len);
        let mut offset = 0u32;
        progress(Progress { done: 0, total });
        while offset < len {
            let end = (offset as usize + chunk).min(image.len());
            let bytes = &image[offset as usize..end];
            let timeout = self.timeouts.reply;
            let r = self.call(
                Command::BankChunk { offset, bytes },
                timeout,
                RETRIES,
                |r| match r {
                    Reply::BankChunk { next } => Some(next),
                    _ => None,
                },
            );
            let next = match r {
                Ok(next) => next,
                // A retry after a lost acknowledgement: the device already has it.
                Err(ClientError::Refused {
                    error: LinkError::OutOfOrder { expected },
                    ..
                }) if expected == end as u32 => expected,
                Err(e) => return Err(lost_upload(e)),
            };
            if next != end as u32 {
                return Err(ClientError::Protocol(
                    "a chunk acknowledged at another offset",
                ));
            }
            offset = next;
            progress(Progress {
                done: u64::from(offset),
                total,
            });
        }
        let timeout = self.timeouts.erase;
        let (got, slots) = self
            .call_watched(Command::BankCommit, timeout, |r| match r {
                Reply::BankCommit { crc, slots } => Some((crc, slots)),
                _ => None,
            })
            .map_err(lost_upload)?;
        if got != crc {
            return Err(ClientError::Verify(VerifyError::CommitCrc {
                expected: crc,
                got,
            }));
        }
        Ok(slots)
    }

    /// Abandons an upload in progress (the region stays erased).
    pub fn abort_upload(&mut self) -> Result<(), ClientError> {
        let timeout = self.timeouts.reply;
        self.call(Command::BankAbort, timeout, RETRIES, |r| match r {
            Reply::BankAbort => Some(()),
            _ => None,
        })
    }

    /// Waits for a restarted device to answer (`hello`), for at most the restart
    /// timeout. The device restarts after its reply to a commit went out: the first
    /// moments are left to it, so that the old firmware cannot answer. A hello sent
    /// while it boots is lost: it is asked again every 50 ms, not after a
    /// whole reply timeout.
    pub fn reconnect(&mut self) -> Result<String, ClientError> {
        let start = self.transport.now();
        // A port that vanished with the restart (USB) fails here: the hello says so.
        let _ = self.pump(RESTART_GRACE);
        self.decoder.reset();
        self.inbox.clear();
        let reply = self.timeouts.reply;
        self.timeouts.reply = RESTART_POLL.min(reply);
        let r = loop {
            match self.hello() {
                Ok(firmware) => break Ok(firmware),
                Err(ClientError::Timeout { .. } | ClientError::Unreadable { .. })
                    if self.transport.now() - start < self.timeouts.restart => {}
                Err(e) => break Err(e),
            }
        };
        self.timeouts.reply = reply;
        r
    }

    /// Checks that the device plays `image` from its bank region: its summary says
    /// so, and every byte read back is the image's. (Bytes, not a CRC of them: a
    /// bank ends with its own CRC, so the CRC-32 of any intact bank image is the
    /// same constant, 0x2144DF1C.)
    pub fn verify(
        &mut self,
        image: &[u8],
        progress: impl FnMut(Progress),
    ) -> Result<(), ClientError> {
        let expected = image.len() as u32;
        match self.info()?.bank {
            BankState::Flashed(s) if s.len == expected => {}
            BankState::Flashed(s) => {
                return Err(ClientError::Verify(VerifyError::Length {
                    expected,
                    got: s.len,
                }))
            }
            _ => return Err(ClientError::Verify(VerifyError::NotFlashed)),
        }
        let back = self.read_bank(0, expected, progress)?;
        if let Some(at) = (0..image.len()).find(|&i| back.get(i) != Some(&image[i])) {
            return Err(ClientError::Verify(VerifyError::Byte(at)));
        }
        Ok(())
    }
}
