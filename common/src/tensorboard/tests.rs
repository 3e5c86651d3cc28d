//! Event files read back by an independent decoder: every CRC checked, every field parsed.

use super::*;

/// What a decoded event holds (the fields this module writes).
#[derive(Debug, Default, PartialEq)]
struct Event {
    wall_time: f64,
    step: u64,
    file_version: Option<String>,
    values: Vec<(String, f32)>,
}

/// Reads every record of `path`, checking both CRCs of each.
fn records(path: &Path) -> Vec<Vec<u8>> {
    let data = std::fs::read(path).expect("read");
    let (mut at, mut out) = (0, Vec::new());
    let u32_at = |i: usize| u32::from_le_bytes(data[i..i + 4].try_into().expect("4 bytes"));
    while at < data.len() {
        let len_bytes = &data[at..at + 8];
        assert_eq!(u32_at(at + 8), masked_crc(len_bytes), "length CRC at {at}");
        let len = u64::from_le_bytes(len_bytes.try_into().expect("8 bytes")) as usize;
        let body = &data[at + 12..at + 12 + len];
        assert_eq!(u32_at(at + 12 + len), masked_crc(body), "data CRC at {at}");
        out.push(body.to_vec());
        at += 16 + len;
    }
    assert_eq!(at, data.len(), "no trailing bytes");
    out
}

/// A protobuf message's fields as (field number, wire type, payload).
fn fields(mut b: &[u8]) -> Vec<(u64, u8, Vec<u8>)> {
    fn varint(b: &mut &[u8]) -> u64 {
        let (mut v, mut shift) = (0u64, 0);
        loop {
            let byte = b[0];
            *b = &b[1..];
            v |= u64::from(byte & 0x7f) << shift;
            if byte < 0x80 {
                return v;
            }
            shift += 7;
        }
    }
    let mut out = Vec::new();
    while !b.is_empty() {
        let k = varint(&mut b);
        let wire = (k & 7) as u8;
        let payload = match wire {
            0 => varint(&mut b).to_le_bytes().to_vec(),
            1 | 5 => {
                let n = if wire == 1 { 8 } else { 4 };
                let (p, rest) = b.split_at(n);
                b = rest;
                p.to_vec()
            }
            2 => {
                let n = varint(&mut b) as usize;
                let (p, rest) = b.split_at(n);
                b = rest;
                p.to_vec()
            }
            w => panic!("wire type {w}"),
        };
        out.push((k >> 3, wire, payload));
    }
    out
}

fn event(body: &[u8]) -> Event {
    let mut e = Event::default();
    for (field, _, p) in fields(body) {
        match field {
            1 => e.wall_time = f64::from_le_bytes(p.try_into().expect("double")),
            2 => e.step = u64::from_le_bytes(p.try_into().expect("varint")),
            3 => e.file_version = Some(String::from_utf8(p).expect("utf-8")),
            5 => {
                for (_, _, value) in fields(&p) {
                    let (mut tag, mut v) = (String::new(), f32::NAN);
                    for (f, _, q) in fields(&value) {
                        match f {
                            1 => tag = String::from_utf8(q).expect("utf-8"),
                            2 => v = f32::from_le_bytes(q.try_into().expect("float")),
                            other => panic!("Summary.Value field {other}"),
                        }
                    }
                    e.values.push((tag, v));
                }
            }
            other => panic!("Event field {other}"),
        }
    }
    e
}

#[test]
fn event_files_round_trip_with_every_crc_checked() {
    let dir = tempfile::tempdir().expect("tempdir");
    let mut w = EventWriter::create(&dir.path().join("learner")).expect("create");
    let name = w
        .path()
        .file_name()
        .expect("name")
        .to_string_lossy()
        .into_owned();
    assert!(name.starts_with("events.out.tfevents."), "{name}");
    w.scalars(
        2048,
        &[("Losses/Policy Loss", -0.0125), ("Policy/Entropy", 2.84)],
    )
    .expect("write");
    w.scalars(300_000_000_000, &[("lavatube/approx_kl", 1e-3)])
        .expect("write");
    let events: Vec<Event> = records(w.path()).iter().map(|r| event(r)).collect();
    assert_eq!(events.len(), 3);
    assert_eq!(events[0].file_version.as_deref(), Some(FILE_VERSION));
    assert!(
        events[0].wall_time > 1.7e9,
        "wall time in seconds since 1970"
    );
    assert_eq!(events[1].step, 2048);
    assert_eq!(
        events[1].values,
        [
            ("Losses/Policy Loss".to_string(), -0.0125f32),
            ("Policy/Entropy".to_string(), 2.84f32)
        ]
    );
    assert_eq!(
        events[2].step, 300_000_000_000,
        "steps past 2^32 (multi-byte varint)"
    );
    assert_eq!(
        events[2].values,
        [("lavatube/approx_kl".to_string(), 1e-3f32)]
    );
}

#[test]
fn masked_crc_matches_tensorflow() {
    // CRC-32C's check value of "123456789" is 0xE3069283 (RFC 3720); rotated right by 15
    // bits (0x25078E0D) plus 0xA282EAD8, by hand: 0xC78AB0E5.
    assert_eq!(masked_crc(b"123456789"), 0xc78a_b0e5);
}
