//! Both transports' sending side as one [`Link`]: iceoryx2 (the runtime's own channels) and
//! the Unix socket, whose frames are a stamp, a length and the payload.

use super::protocol::{Stamp, TIMEOUT};
use anyhow::{Context, bail};
use common::ipc::{Receiver, Sender};
use iceoryx2::prelude::ZeroCopySend;
use std::io::{ErrorKind, Read, Write};
use std::os::unix::net::UnixStream;
use std::time::{Duration, Instant};

/// Socket frame: the stamp, the payload length, the payload.
pub(super) const FRAME_HEADER: usize = 32;

pub(super) fn encode(stamp: &Stamp, len: u64, out: &mut [u8]) {
    out[0..8].copy_from_slice(&stamp.seq.to_le_bytes());
    out[8..16].copy_from_slice(&stamp.sent_ns.to_le_bytes());
    out[16..20].copy_from_slice(&stamp.test.to_le_bytes());
    out[20..24].copy_from_slice(&stamp.flags.to_le_bytes());
    out[24..32].copy_from_slice(&len.to_le_bytes());
}

/// Reads a frame header; `None` when the socket closed before one began.
pub(super) fn read_header(stream: &mut UnixStream) -> anyhow::Result<Option<(Stamp, usize)>> {
    let mut b = [0u8; FRAME_HEADER];
    match stream.read_exact(&mut b) {
        Ok(()) => {}
        Err(e) if e.kind() == ErrorKind::UnexpectedEof => return Ok(None),
        Err(e) => return Err(e).context("socket read"),
    }
    let u64_at = |i: usize| {
        let mut w = [0u8; 8];
        w.copy_from_slice(&b[i..i + 8]);
        u64::from_le_bytes(w)
    };
    let u32_at = |i: usize| {
        let mut w = [0u8; 4];
        w.copy_from_slice(&b[i..i + 4]);
        u32::from_le_bytes(w)
    };
    let stamp = Stamp {
        seq: u64_at(0),
        sent_ns: u64_at(8),
        test: u32_at(16),
        flags: u32_at(20),
    };
    let len = usize::try_from(u64_at(24)).context("frame length")?;
    Ok(Some((stamp, len)))
}

/// The sending side of one transport.
pub(super) trait Link {
    fn send(&mut self, stamp: Stamp) -> anyhow::Result<()>;
    /// Waits for at least one acknowledgement; the highest count acknowledged.
    fn acked(&mut self) -> anyhow::Result<u64>;
}

pub(super) struct IpcLink<'a, T: std::fmt::Debug + Copy + ZeroCopySend + 'static> {
    pub(super) tx: &'a Sender<T, Stamp>,
    pub(super) data: &'a [T],
    pub(super) acks: &'a Receiver<u64, Stamp>,
}

impl<T: std::fmt::Debug + Copy + Default + ZeroCopySend + 'static> Link for IpcLink<'_, T> {
    fn send(&mut self, stamp: Stamp) -> anyhow::Result<()> {
        Ok(self.tx.send(stamp, self.data)?)
    }

    fn acked(&mut self) -> anyhow::Result<u64> {
        let since = Instant::now();
        loop {
            let mut best = None;
            while let Some(s) = self.acks.try_recv()? {
                best = best.max(s.payload().first().copied());
            }
            if let Some(n) = best {
                return Ok(n);
            }
            if since.elapsed() > TIMEOUT {
                bail!("no acknowledgement over iceoryx2 for {TIMEOUT:?}");
            }
            self.acks.wait(Duration::from_millis(100))?;
        }
    }
}

pub(super) struct SocketLink<'a> {
    pub(super) stream: &'a mut UnixStream,
    /// Header and payload, sent with one write.
    pub(super) frame: Vec<u8>,
}

impl Link for SocketLink<'_> {
    fn send(&mut self, stamp: Stamp) -> anyhow::Result<()> {
        let len = (self.frame.len() - FRAME_HEADER) as u64;
        encode(&stamp, len, &mut self.frame[..FRAME_HEADER]);
        self.stream.write_all(&self.frame).context("socket write")
    }

    fn acked(&mut self) -> anyhow::Result<u64> {
        let mut b = [0u8; 8];
        self.stream
            .read_exact(&mut b)
            .context("no acknowledgement over the socket")?;
        Ok(u64::from_le_bytes(b))
    }
}
