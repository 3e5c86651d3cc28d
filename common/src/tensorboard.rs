//! TensorBoard event files, so `tensorboard --logdir runs/` shows a run as ML-Agents and
//! Stable-Baselines3 users expect.
//!
//! The format is TFRecord framing around `tensorflow.Event` protobufs: each record is its
//! length (u64, little-endian), the masked CRC-32C of those 8 bytes, the bytes, and the masked
//! CRC-32C of the bytes. The first event carries `file_version = "brain.Event:2"`; each later
//! one a wall time, a step and a `Summary` of `{tag, simple_value}` pairs. The few protobuf
//! fields needed are encoded here by hand rather than through a code generator.
//!
//! Each record goes to the file in one `write` call, so a crash leaves at most a torn last
//! record, which TensorBoard's reader skips.

use std::fs::File;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::time::{SystemTime, UNIX_EPOCH};

/// What the first event of a file says: TensorBoard refuses files without it.
pub const FILE_VERSION: &str = "brain.Event:2";

/// One event file, appended a record at a time.
pub struct EventWriter {
    path: PathBuf,
    file: File,
}

impl EventWriter {
    /// A new event file in `dir` (made if missing), named as TensorBoard looks for them:
    /// `events.out.tfevents.<unix seconds>.<host>.<pid>`, plus `.1`, `.2`, … when the
    /// process made one there in the same second. A restarted process starts a new one,
    /// which TensorBoard reads after the earlier ones of the directory.
    pub fn create(dir: &Path) -> std::io::Result<Self> {
        std::fs::create_dir_all(dir)?;
        let stem = format!(
            "events.out.tfevents.{:.0}.{}.{}",
            now().trunc(),
            hostname(),
            std::process::id()
        );
        let mut n = 0;
        let (path, file) = loop {
            let path = dir.join(match n {
                0 => stem.clone(),
                n => format!("{stem}.{n}"),
            });
            match std::fs::OpenOptions::new()
                .create_new(true)
                .write(true)
                .open(&path)
            {
                Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => n += 1,
                opened => break (path, opened?),
            }
        };
        let mut writer = Self { path, file };
        let mut event = Vec::new();
        double(&mut event, 1, now());
        bytes(&mut event, 3, FILE_VERSION.as_bytes());
        writer.record(&event)?;
        Ok(writer)
    }

    pub fn path(&self) -> &Path {
        &self.path
    }

    /// One event at `step` holding every `(tag, value)` pair as a scalar.
    pub fn scalars(&mut self, step: u64, values: &[(&str, f64)]) -> std::io::Result<()> {
        let mut summary = Vec::new();
        for (tag, v) in values {
            let mut value = Vec::new();
            bytes(&mut value, 1, tag.as_bytes());
            // `simple_value` is a float: TensorBoard shows scalars at f32 precision.
            key(&mut value, 2, FIXED32);
            value.extend_from_slice(&(*v as f32).to_le_bytes());
            bytes(&mut summary, 1, &value);
        }
        let mut event = Vec::new();
        double(&mut event, 1, now());
        key(&mut event, 2, VARINT);
        varint(&mut event, step);
        bytes(&mut event, 5, &summary);
        self.record(&event)
    }

    /// Frames `data` as one TFRecord and writes it in one call.
    fn record(&mut self, data: &[u8]) -> std::io::Result<()> {
        let len = (data.len() as u64).to_le_bytes();
        let mut rec = Vec::with_capacity(data.len() + 16);
        rec.extend_from_slice(&len);
        rec.extend_from_slice(&masked_crc(&len).to_le_bytes());
        rec.extend_from_slice(data);
        rec.extend_from_slice(&masked_crc(data).to_le_bytes());
        self.file.write_all(&rec)?;
        self.file.flush()
    }
}

/// TFRecord's masked CRC-32C: the CRC rotated right by 15 bits plus a constant, so that a
/// CRC stored inside checksummed data does not checksum to a fixed value.
pub fn masked_crc(data: &[u8]) -> u32 {
    let crc = crc32c::crc32c(data);
    crc.rotate_right(15).wrapping_add(0xa282_ead8)
}

const VARINT: u8 = 0;
const FIXED64: u8 = 1;
const LEN: u8 = 2;
const FIXED32: u8 = 5;

fn key(out: &mut Vec<u8>, field: u32, wire: u8) {
    varint(out, u64::from(field << 3 | u32::from(wire)));
}

fn varint(out: &mut Vec<u8>, mut v: u64) {
    while v >= 0x80 {
        out.push((v as u8) | 0x80);
        v >>= 7;
    }
    out.push(v as u8);
}

fn double(out: &mut Vec<u8>, field: u32, v: f64) {
    key(out, field, FIXED64);
    out.extend_from_slice(&v.to_le_bytes());
}

fn bytes(out: &mut Vec<u8>, field: u32, b: &[u8]) {
    key(out, field, LEN);
    varint(out, b.len() as u64);
    out.extend_from_slice(b);
}

fn now() -> f64 {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or(0.0, |d| d.as_secs_f64())
}

/// This machine's name, for the event file's name; `localhost` if it has none.
fn hostname() -> String {
    let mut buf = [0u8; 256];
    // SAFETY: gethostname(2) writes at most `buf.len()` bytes into our buffer.
    let r = unsafe { libc::gethostname(buf.as_mut_ptr().cast(), buf.len()) };
    let len = buf.iter().position(|&b| b == 0).unwrap_or(buf.len());
    match std::str::from_utf8(&buf[..len]) {
        Ok(name) if r == 0 && !name.is_empty() => name.replace(['/', '.'], "_"),
        _ => "localhost".into(),
    }
}

#[cfg(test)]
mod tests;
