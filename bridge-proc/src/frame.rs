//! Frames: one message of a run's service as bytes between hosts (DESIGN §9).
//!
//! Layout, little-endian:
//!
//! | bytes | field |
//! |---|---|
//! | 4 | magic `LVTB` |
//! | 2 | frame version (2) |
//! | 1 | kind: 1 rollout chunk, 2 policy |
//! | 1 | reserved, 0 |
//! | 96 | the message types' names, `header[element]`, zero-padded |
//! | 4, 4, 4 | header size, element size, elements |
//! | 4 | source: the sim host's id (rollouts) or the policy slot (policies) |
//! | 8 | sequence number, per kind and source, from 0 |
//! | header size | the header, as in shared memory |
//! | element size × elements | the elements, as in shared memory |
//! | 32 | MAC of everything before it: keyed BLAKE3 with the run's shared key |
//!
//! Decoding checks, in order: length, magic and version, the MAC (so nothing else of a frame
//! from outside the run is looked at), kind, type names and sizes. Each refusal has a kind
//! for [`Refusals`](common::refusals::Refusals).
//!
//! The MAC is BLAKE3 in its keyed mode, which its designers specify as a MAC (no HMAC
//! construction needed), under a key derived from the run's secret. HMAC-SHA256 at about
//! 1.6 GB/s would take 0.3 ms of a rollout chunk's trip between hosts (once to send, once
//! to check); BLAKE3 hashes a chunk several times faster.

const MAGIC: [u8; 4] = *b"LVTB";
const VERSION: u16 = 2;
/// BLAKE3's key-derivation context for the frame MAC's key.
const KEY_CONTEXT: &str = "lavatube 2026 frame MAC between hosts, version 2";
const TYPE_NAME_BYTES: usize = 96;
/// Bytes before the header: magic, version, kind, reserved, names, three sizes, source, seq.
const HEAD_BYTES: usize = 4 + 2 + 1 + 1 + TYPE_NAME_BYTES + 4 + 4 + 4 + 4 + 8;
const MAC_BYTES: usize = 32;

/// What a frame carries.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u8)]
pub enum Kind {
    Rollout = 1,
    Policy = 2,
}

/// A wire type that crosses hosts as its bytes.
///
/// # Safety
///
/// The type is `repr(C)`, has no padding (its layout test in `common` pins every offset), and
/// every bit pattern of its size is a valid value (its fields are integers, floats and arrays
/// of them), so its bytes may be read and any bytes of its size may become one.
pub unsafe trait Plain: Copy + iceoryx2::prelude::ZeroCopySend {}

// SAFETY: repr(C) integers with no padding: `rollout_header_layout`.
unsafe impl Plain for common::wire::RolloutHeader {}
// SAFETY: repr(C) integers and floats, no padding: `policy_header_layout_and_round_trip`.
unsafe impl Plain for common::wire::PolicyHeader {}
// SAFETY: repr(C) floats, integers and u8s with explicit reserved bytes: `transition_layout_is_pinned`.
unsafe impl Plain for common::Transition {}
// SAFETY: a float.
unsafe impl Plain for f32 {}

fn bytes_of<T: Plain>(values: &[T]) -> &[u8] {
    // SAFETY: `Plain` types have no padding, so every byte is initialised; the length is the
    // slice's size in bytes.
    unsafe { std::slice::from_raw_parts(values.as_ptr().cast::<u8>(), size_of_val(values)) }
}

/// Replaces `out` with the values in `bytes` (a whole number of them), reusing its memory.
fn read_plain<T: Plain>(bytes: &[u8], out: &mut Vec<T>) {
    let n = bytes.len() / size_of::<T>();
    debug_assert_eq!(n * size_of::<T>(), bytes.len());
    out.clear();
    out.reserve(n);
    // SAFETY: `out` has room for `n` values, `bytes` holds exactly `n × size_of::<T>()`
    // bytes, the two do not overlap, and any bytes make a `Plain` value; copied as bytes
    // because network buffers have no alignment.
    unsafe {
        std::ptr::copy_nonoverlapping(
            bytes.as_ptr(),
            out.as_mut_ptr().cast::<u8>(),
            n * size_of::<T>(),
        );
        out.set_len(n);
    }
}

/// `header[element]`: the names both ends must agree on, as iceoryx2 checks them locally.
pub fn type_names<H: Plain, T: Plain>() -> String {
    // SAFETY: `type_name` only returns the name the derive gave the type.
    let (h, t) = unsafe {
        (
            <H as iceoryx2::prelude::ZeroCopySend>::type_name(),
            <T as iceoryx2::prelude::ZeroCopySend>::type_name(),
        )
    };
    format!("{h}[{t}]")
}

/// The run's shared key, as the MAC's 32-byte key derived from the secret.
#[derive(Clone)]
pub struct Key([u8; 32]);

impl Key {
    /// The key of a secret of any length.
    pub fn new(secret: &[u8]) -> Self {
        Self(blake3::derive_key(KEY_CONTEXT, secret))
    }

    fn mac(&self, bytes: &[u8]) -> blake3::Hash {
        blake3::keyed_hash(&self.0, bytes)
    }
}

impl std::fmt::Debug for Key {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("Key(..)")
    }
}

/// A decoded frame's header fields; its elements go to the caller's buffer.
#[derive(Debug, Clone, PartialEq)]
pub struct Frame<H> {
    pub source: u32,
    pub seq: u64,
    pub header: H,
}

/// Why a frame was refused.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Refused {
    /// Counted by this, e.g. `"wrong key"`.
    pub kind: &'static str,
    pub detail: String,
}

fn refused(kind: &'static str, detail: impl Into<String>) -> Refused {
    Refused {
        kind,
        detail: detail.into(),
    }
}

/// The frame of one message.
pub fn encode<H: Plain, T: Plain>(
    key: &Key,
    kind: Kind,
    source: u32,
    seq: u64,
    header: &H,
    items: &[T],
) -> Vec<u8> {
    let names = type_names::<H, T>();
    let mut out = Vec::with_capacity(HEAD_BYTES + size_of::<H>() + size_of_val(items) + MAC_BYTES);
    out.extend(MAGIC);
    out.extend(VERSION.to_le_bytes());
    out.extend([kind as u8, 0]);
    let mut name = [0u8; TYPE_NAME_BYTES];
    let n = names.len().min(TYPE_NAME_BYTES);
    name[..n].copy_from_slice(&names.as_bytes()[..n]);
    out.extend(name);
    for v in [size_of::<H>(), size_of::<T>(), items.len()] {
        out.extend(u32::try_from(v).unwrap_or(u32::MAX).to_le_bytes());
    }
    out.extend(source.to_le_bytes());
    out.extend(seq.to_le_bytes());
    out.extend(bytes_of(std::slice::from_ref(header)));
    out.extend(bytes_of(items));
    let mac = key.mac(&out);
    out.extend(mac.as_bytes());
    out
}

fn u32_at(b: &[u8], at: usize) -> u32 {
    u32::from_le_bytes([b[at], b[at + 1], b[at + 2], b[at + 3]])
}

/// Checks and decodes a frame of `kind` carrying `H` and `T`; its elements replace `items`'s
/// (left as they were when the frame is refused).
pub fn decode<H: Plain, T: Plain>(
    key: &Key,
    kind: Kind,
    bytes: &[u8],
    items: &mut Vec<T>,
) -> Result<Frame<H>, Refused> {
    if bytes.len() < HEAD_BYTES + MAC_BYTES {
        return Err(refused("malformed", format!("{} bytes", bytes.len())));
    }
    if bytes[..4] != MAGIC || u16::from_le_bytes([bytes[4], bytes[5]]) != VERSION {
        return Err(refused("malformed", "not a lavatube frame of version 2"));
    }
    let (body, tag) = bytes.split_at(bytes.len() - MAC_BYTES);
    // blake3::Hash compares in constant time.
    if key.mac(body) != blake3::Hash::from_slice(tag).unwrap_or_else(|_| unreachable!()) {
        return Err(refused(
            "wrong key",
            "its MAC does not match the run's key (net.key-file)",
        ));
    }
    if bytes[6] != kind as u8 {
        return Err(refused(
            "wrong kind",
            format!("kind {} where {} was expected", bytes[6], kind as u8),
        ));
    }
    let names = &bytes[8..8 + TYPE_NAME_BYTES];
    let names = String::from_utf8_lossy(
        &names[..names
            .iter()
            .position(|&b| b == 0)
            .unwrap_or(TYPE_NAME_BYTES)],
    );
    let at = 8 + TYPE_NAME_BYTES;
    let (h_size, t_size, n) = (
        u32_at(bytes, at),
        u32_at(bytes, at + 4),
        u32_at(bytes, at + 8),
    );
    let ours = type_names::<H, T>();
    if *names != ours || h_size as usize != size_of::<H>() || t_size as usize != size_of::<T>() {
        return Err(refused(
            "different message types",
            format!(
                "the run's processes use a different version of its message types (this one: `{ours}`, {} + {} bytes; the frame's: `{names}`, {h_size} + {t_size} bytes); build every host from one checkout",
                size_of::<H>(),
                size_of::<T>()
            ),
        ));
    }
    let payload = &body[HEAD_BYTES..];
    let want = (n as usize)
        .checked_mul(size_of::<T>())
        .and_then(|b| b.checked_add(size_of::<H>()));
    if want != Some(payload.len()) {
        return Err(refused(
            "malformed",
            format!("{n} elements announced, {} bytes carried", payload.len()),
        ));
    }
    let (header, elements) = payload.split_at(size_of::<H>());
    // SAFETY: `header` is `size_of::<H>()` bytes and any bytes make a `Plain` value.
    let header = unsafe { std::ptr::read_unaligned(header.as_ptr().cast::<H>()) };
    read_plain(elements, items);
    Ok(Frame {
        source: u32_at(bytes, at + 12),
        seq: u64::from_le_bytes(bytes[at + 16..at + 24].try_into().unwrap_or_default()),
        header,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use common::Transition;
    use common::wire::{PolicyHeader, RolloutHeader};
    use proptest::prelude::*;

    fn key() -> Key {
        Key::new(&[42u8; 32])
    }

    fn chunk() -> (RolloutHeader, Vec<Transition>) {
        let h = RolloutHeader {
            chunk: 7,
            env_steps: 1 << 33,
            steps: 2,
            envs: 1,
            source: 3,
            _reserved: 0,
        };
        let items = (0..3)
            .map(|i| Transition {
                reward: i as f32 * 0.5,
                env: 0,
                policy_version: 11,
                ..Transition::default()
            })
            .collect();
        (h, items)
    }

    #[test]
    fn a_frame_round_trips_bit_for_bit() {
        let (h, items) = chunk();
        let bytes = encode(&key(), Kind::Rollout, 3, 9, &h, &items);
        let expected =
            HEAD_BYTES + size_of::<RolloutHeader>() + 3 * size_of::<Transition>() + MAC_BYTES;
        assert_eq!(bytes.len(), expected);
        // A used buffer is reused: its old contents do not leak into the frame's.
        let mut got = vec![Transition::default(); 7];
        let f = decode::<RolloutHeader, Transition>(&key(), Kind::Rollout, &bytes, &mut got)
            .expect("decodes");
        assert_eq!((f.source, f.seq, f.header), (3, 9, h));
        assert_eq!(got, items);
    }

    #[test]
    fn frames_from_outside_the_run_or_of_other_types_are_refused_by_kind() {
        let (h, items) = chunk();
        let bytes = encode(&key(), Kind::Rollout, 3, 0, &h, &items);
        let kind_of = |b: &[u8]| {
            decode::<RolloutHeader, Transition>(&key(), Kind::Rollout, b, &mut Vec::new())
                .expect_err("refused")
                .kind
        };
        let other = encode(&Key::new(&[1u8; 32]), Kind::Rollout, 3, 0, &h, &items);
        assert_eq!(kind_of(&other), "wrong key");
        let mut flipped = bytes.clone();
        flipped[HEAD_BYTES + 5] ^= 1;
        assert_eq!(
            kind_of(&flipped),
            "wrong key",
            "a changed byte breaks the MAC"
        );
        assert_eq!(kind_of(&bytes[..bytes.len() - 1]), "wrong key");
        assert_eq!(kind_of(&bytes[..10]), "malformed");
        let policy = encode(
            &key(),
            Kind::Policy,
            0,
            0,
            &PolicyHeader::default(),
            &[0.5f32; 4],
        );
        assert_eq!(kind_of(&policy), "wrong kind");
        let e = decode::<PolicyHeader, f32>(&key(), Kind::Rollout, &bytes, &mut Vec::new())
            .expect_err("types");
        assert_eq!(e.kind, "different message types");
        assert!(
            e.detail.contains("different version of its message types"),
            "{}",
            e.detail
        );
        assert!(
            e.detail
                .contains("lavatube.RolloutHeader.v3[lavatube.Transition.v1]"),
            "{}",
            e.detail
        );
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(10_000))]

        /// Random bytes, and random bytes behind a valid-looking start, are refused, never a panic.
        #[test]
        fn random_bytes_are_refused(tail in proptest::collection::vec(any::<u8>(), 0..400), lie in any::<bool>()) {
            let mut bytes = Vec::new();
            if lie {
                bytes.extend(MAGIC);
                bytes.extend(VERSION.to_le_bytes());
            }
            bytes.extend(tail);
            let r = decode::<RolloutHeader, Transition>(&key(), Kind::Rollout, &bytes, &mut Vec::new());
            prop_assert!(r.is_err());
        }
    }
}
