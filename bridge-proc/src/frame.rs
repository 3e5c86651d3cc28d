//! Frames: one message of a run's service as bytes between hosts (DESIGN §9), sealed so that
//! only holders of the run's key can read or make one.
//!
//! Layout, little-endian:
//!
//! | bytes | field |
//! |---|---|
//! | 4 | magic `LVTB` |
//! | 2 | frame version (3) |
//! | 1 | kind: 1 rollout chunk, 2 policy |
//! | 1 | reserved, 0 |
//! | 96 | the message types' names, `header[element]`, zero-padded |
//! | 4, 4, 4 | header size, element size, elements |
//! | 4 | source: the sim host's id (rollouts) or the policy slot (policies) |
//! | 8 | epoch: the sender's random id for this start of its bridge |
//! | 8 | sequence number, per sender and epoch, from 0 |
//! | 8 | start: the learner host bridge's random id for this start of the run |
//! | header size + element size × elements | the header and elements, as in shared memory, encrypted |
//! | 16 | AES-256-GCM tag over all of the above |
//!
//! Everything before the encrypted part is the AEAD's associated data: an observer sees the
//! sizes, source, epoch, sequence number and start, never a header, transition or weight.
//! Each sender (kind, source, epoch) seals under its own key, derived from the run's secret,
//! with its sequence number as the nonce, so no nonce repeats under a key.
//!
//! Decoding checks, in order: length, magic and version, the tag (so nothing else of a frame
//! from outside the run is looked at), kind, type names and sizes. Each refusal has a kind
//! for [`Refusals`](common::refusals::Refusals). Whether a sealed frame is new to its
//! receiver is [`Streams`]'s question.
//!
//! AES-256-GCM by `ring`: sealing and opening a 230 KB rollout chunk took 95–107 µs here,
//! against 400–450 µs for RustCrypto's AES-256-GCM and ChaCha20-Poly1305 and 127–149 µs for
//! the keyed-BLAKE3 MAC that only authenticated the previous frame version (docs/RESULTS.md).

use ring::aead::{AES_256_GCM, Aad, LessSafeKey, NONCE_LEN, Nonce, UnboundKey};
use std::collections::{BTreeMap, BTreeSet};

const MAGIC: [u8; 4] = *b"LVTB";
const VERSION: u16 = 3;
/// BLAKE3's key-derivation context for the run's frame key.
const KEY_CONTEXT: &str = "lavatube 2026 frame AEAD between hosts, version 3";
const TYPE_NAME_BYTES: usize = 96;
/// Where the source, epoch, sequence number and run start begin.
const STAMP_AT: usize = 4 + 2 + 1 + 1 + TYPE_NAME_BYTES + 4 + 4 + 4;
/// Bytes before the encrypted part.
const HEAD_BYTES: usize = STAMP_AT + 4 + 8 + 8 + 8;
const TAG_BYTES: usize = 16;

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

/// The run's frame key, derived from its secret; each sender's sealing key derives from it.
#[derive(Clone)]
pub struct Key([u8; 32]);

impl Key {
    /// The key of a secret of any length.
    pub fn new(secret: &[u8]) -> Self {
        Self(blake3::derive_key(KEY_CONTEXT, secret))
    }

    /// The AES-256-GCM key of one sender: frames of `kind` from `source` in `epoch`.
    fn sender(&self, kind: u8, source: u32, epoch: u64) -> LessSafeKey {
        let mut id = [0u8; 13];
        id[0] = kind;
        id[1..5].copy_from_slice(&source.to_le_bytes());
        id[5..].copy_from_slice(&epoch.to_le_bytes());
        let bytes = blake3::keyed_hash(&self.0, &id);
        // A 32-byte key is what AES-256 takes; `new` fails only on a wrong length.
        let key = UnboundKey::new(&AES_256_GCM, bytes.as_bytes())
            .unwrap_or_else(|_| unreachable!("a 32-byte AES-256 key"));
        LessSafeKey::new(key)
    }
}

impl std::fmt::Debug for Key {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("Key(..)")
    }
}

/// Where a frame sits: who sent it, in which start of its bridge, its place in that sender's
/// stream, and the start of the run it belongs to.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Stamp {
    pub source: u32,
    pub epoch: u64,
    pub seq: u64,
    pub start: u64,
}

/// A decoded frame's stamp and header; its elements go to the caller's buffer.
#[derive(Debug, Clone, PartialEq)]
pub struct Frame<H> {
    pub stamp: Stamp,
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

/// The nonce of a sender's frame `seq`: unique under that sender's key.
fn nonce(seq: u64) -> Nonce {
    let mut n = [0u8; NONCE_LEN];
    n[..8].copy_from_slice(&seq.to_le_bytes());
    Nonce::assume_unique_for_key(n)
}

/// One sender's frames of one kind: its key, its epoch (a random id for this start) and its
/// next sequence number.
pub struct Sealer {
    key: LessSafeKey,
    kind: Kind,
    source: u32,
    epoch: u64,
    next: u64,
}

impl Sealer {
    /// Frames of `kind` from `source`, in a new random epoch.
    pub fn new(key: &Key, kind: Kind, source: u32) -> Self {
        Self::in_epoch(key, kind, source, new_id())
    }

    /// Frames of `kind` from `source` in the given `epoch`, whose sequence starts at 0.
    pub fn in_epoch(key: &Key, kind: Kind, source: u32, epoch: u64) -> Self {
        Self {
            key: key.sender(kind as u8, source, epoch),
            kind,
            source,
            epoch,
            next: 0,
        }
    }

    pub fn source(&self) -> u32 {
        self.source
    }

    /// The next frame: `header` and `items`, sealed, of run start `start`.
    pub fn seal<H: Plain, T: Plain>(&mut self, start: u64, header: &H, items: &[T]) -> Vec<u8> {
        let seq = self.next;
        self.next += 1;
        let names = type_names::<H, T>();
        let mut out =
            Vec::with_capacity(HEAD_BYTES + size_of::<H>() + size_of_val(items) + TAG_BYTES);
        out.extend(MAGIC);
        out.extend(VERSION.to_le_bytes());
        out.extend([self.kind as u8, 0]);
        let mut name = [0u8; TYPE_NAME_BYTES];
        let n = names.len().min(TYPE_NAME_BYTES);
        name[..n].copy_from_slice(&names.as_bytes()[..n]);
        out.extend(name);
        for v in [size_of::<H>(), size_of::<T>(), items.len()] {
            out.extend(u32::try_from(v).unwrap_or(u32::MAX).to_le_bytes());
        }
        out.extend(self.source.to_le_bytes());
        out.extend(self.epoch.to_le_bytes());
        out.extend(seq.to_le_bytes());
        out.extend(start.to_le_bytes());
        out.extend(bytes_of(std::slice::from_ref(header)));
        out.extend(bytes_of(items));
        let (aad, data) = out.split_at_mut(HEAD_BYTES);
        let tag = self
            .key
            .seal_in_place_separate_tag(nonce(seq), Aad::from(&*aad), data)
            .unwrap_or_else(|_| unreachable!("a frame is far below AES-GCM's length limit"));
        out.extend(tag.as_ref());
        out
    }
}

/// A random id, never 0: a sender's epoch, a start of the run.
pub fn new_id() -> u64 {
    let mut b = [0u8; 8];
    // The kernel's random source; if it cannot answer, the clock in nanoseconds still differs
    // between two starts of a bridge.
    if getrandom(&mut b).is_err() {
        b = (std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map_or(1, |d| d.as_nanos() as u64))
        .to_le_bytes();
    }
    u64::from_le_bytes(b).max(1)
}

fn getrandom(out: &mut [u8]) -> Result<(), ring::error::Unspecified> {
    use ring::rand::SecureRandom;
    ring::rand::SystemRandom::new().fill(out)
}

fn u32_at(b: &[u8], at: usize) -> u32 {
    u32::from_le_bytes([b[at], b[at + 1], b[at + 2], b[at + 3]])
}

fn u64_at(b: &[u8], at: usize) -> u64 {
    let mut v = [0u8; 8];
    v.copy_from_slice(&b[at..at + 8]);
    u64::from_le_bytes(v)
}

/// Opens frames: the run's key, each sender's derived key kept while it is in use, and the
/// memory a frame is decrypted into.
pub struct Opener {
    key: Key,
    senders: BTreeMap<(u8, u32, u64), LessSafeKey>,
    scratch: Vec<u8>,
}

/// Senders whose keys an [`Opener`] keeps; past this it derives them again (a few µs).
const KEPT_SENDERS: usize = 64;

impl Opener {
    pub fn new(key: &Key) -> Self {
        Self {
            key: key.clone(),
            senders: BTreeMap::new(),
            scratch: Vec::new(),
        }
    }

    /// Checks and decodes a frame of `kind` carrying `H` and `T`; its elements replace
    /// `items`'s (left as they were when the frame is refused).
    pub fn open<H: Plain, T: Plain>(
        &mut self,
        kind: Kind,
        bytes: &[u8],
        items: &mut Vec<T>,
    ) -> Result<Frame<H>, Refused> {
        if bytes.len() < HEAD_BYTES + TAG_BYTES {
            return Err(refused("malformed", format!("{} bytes", bytes.len())));
        }
        if bytes[..4] != MAGIC || u16::from_le_bytes([bytes[4], bytes[5]]) != VERSION {
            return Err(refused("malformed", "not a lavatube frame of version 3"));
        }
        let stamp = Stamp {
            source: u32_at(bytes, STAMP_AT),
            epoch: u64_at(bytes, STAMP_AT + 4),
            seq: u64_at(bytes, STAMP_AT + 12),
            start: u64_at(bytes, STAMP_AT + 20),
        };
        let (aad, sealed) = bytes.split_at(HEAD_BYTES);
        let id = (bytes[6], stamp.source, stamp.epoch);
        if !self.senders.contains_key(&id) && self.senders.len() >= KEPT_SENDERS {
            self.senders.clear();
        }
        let key = self
            .senders
            .entry(id)
            .or_insert_with(|| self.key.sender(id.0, id.1, id.2));
        self.scratch.clear();
        self.scratch.extend_from_slice(sealed);
        let Ok(plain) = key.open_in_place(nonce(stamp.seq), Aad::from(aad), &mut self.scratch)
        else {
            return Err(refused(
                "wrong key",
                "it does not open under the run's key (net.key-file)",
            ));
        };
        let plain: &[u8] = plain;
        if bytes[6] != kind as u8 {
            return Err(refused(
                "wrong kind",
                format!("kind {} where {} was expected", bytes[6], kind as u8),
            ));
        }
        let n = check_types::<H, T>(bytes)?;
        let want = (n as usize)
            .checked_mul(size_of::<T>())
            .and_then(|b| b.checked_add(size_of::<H>()));
        if want != Some(plain.len()) {
            return Err(refused(
                "malformed",
                format!("{n} elements announced, {} bytes carried", plain.len()),
            ));
        }
        let (header, elements) = plain.split_at(size_of::<H>());
        // SAFETY: `header` is `size_of::<H>()` bytes and any bytes make a `Plain` value.
        let header = unsafe { std::ptr::read_unaligned(header.as_ptr().cast::<H>()) };
        read_plain(elements, items);
        Ok(Frame { stamp, header })
    }
}

/// The number of elements a frame announces, if its type names and sizes are `H`'s and `T`'s.
fn check_types<H: Plain, T: Plain>(bytes: &[u8]) -> Result<u32, Refused> {
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
    Ok(n)
}

/// What a receiver makes of a sealed frame's place in its sender's stream.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Place {
    /// Next in its stream, after `lost` frames that never came.
    New { lost: u64 },
    /// The first of a sender's new epoch (its bridge started again): its earlier epochs are
    /// closed.
    Restarted,
    /// The newest frame of its stream again (a policy query's reply repeats it).
    Last,
}

/// A receiver's memory of each source's stream: which epoch is current, how far it has come,
/// and which epochs are over, so that a frame it has had is never taken again.
#[derive(Debug, Default)]
pub struct Streams {
    current: BTreeMap<u32, (u64, u64)>,
    closed: BTreeSet<(u32, u64)>,
}

impl Streams {
    /// Where a frame of `stamp` sits; refused as "replayed" when its stream has had it, or its
    /// epoch is over.
    pub fn admit(&mut self, stamp: Stamp) -> Result<Place, Refused> {
        let replayed = |why: &str| {
            Err(refused(
                "replayed",
                format!(
                    "source {} epoch {:016x} frame {}: {why}",
                    stamp.source, stamp.epoch, stamp.seq
                ),
            ))
        };
        if self.closed.contains(&(stamp.source, stamp.epoch)) {
            return replayed("an epoch its sender has left");
        }
        match self.current.get_mut(&stamp.source) {
            Some((epoch, next)) if *epoch == stamp.epoch => {
                if stamp.seq >= *next {
                    let lost = stamp.seq - *next;
                    *next = stamp.seq + 1;
                    Ok(Place::New { lost })
                } else if stamp.seq + 1 == *next {
                    Ok(Place::Last)
                } else {
                    replayed("already had")
                }
            }
            Some((epoch, next)) => {
                self.closed.insert((stamp.source, *epoch));
                (*epoch, *next) = (stamp.epoch, stamp.seq + 1);
                Ok(Place::Restarted)
            }
            None => {
                self.current
                    .insert(stamp.source, (stamp.epoch, stamp.seq + 1));
                Ok(Place::New { lost: stamp.seq })
            }
        }
    }

    /// Forgets every stream (the run started again: nothing of the old start can come again
    /// under the new one).
    pub fn clear(&mut self) {
        *self = Self::default();
    }
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

    const START: u64 = 0x5e55;

    fn sealer() -> Sealer {
        Sealer::in_epoch(&key(), Kind::Rollout, 3, 77)
    }

    #[test]
    fn a_frame_round_trips_bit_for_bit_and_hides_what_it_carries() {
        let (h, items) = chunk();
        let mut tx = sealer();
        let bytes = tx.seal(START, &h, &items);
        let expected =
            HEAD_BYTES + size_of::<RolloutHeader>() + 3 * size_of::<Transition>() + TAG_BYTES;
        assert_eq!(bytes.len(), expected);
        let plain = [bytes_of(std::slice::from_ref(&h)), bytes_of(&items)].concat();
        assert_ne!(
            &bytes[HEAD_BYTES..HEAD_BYTES + plain.len()],
            &plain[..],
            "the header and transitions travel encrypted"
        );
        // A used buffer is reused: its old contents do not leak into the frame's.
        let mut got = vec![Transition::default(); 7];
        let f = Opener::new(&key())
            .open::<RolloutHeader, Transition>(Kind::Rollout, &bytes, &mut got)
            .expect("opens");
        let stamp = Stamp {
            source: 3,
            epoch: 77,
            seq: 0,
            start: START,
        };
        assert_eq!((f.stamp, f.header), (stamp, h));
        assert_eq!(got, items);
        let second = tx.seal(START, &h, &items);
        assert_ne!(
            second[HEAD_BYTES..],
            bytes[HEAD_BYTES..],
            "a new nonce per frame"
        );
    }

    #[test]
    fn frames_from_outside_the_run_or_of_other_types_are_refused_by_kind() {
        let (h, items) = chunk();
        let bytes = sealer().seal(START, &h, &items);
        let kind_of = |b: &[u8]| {
            Opener::new(&key())
                .open::<RolloutHeader, Transition>(Kind::Rollout, b, &mut Vec::new())
                .expect_err("refused")
                .kind
        };
        let other =
            Sealer::in_epoch(&Key::new(&[1u8; 32]), Kind::Rollout, 3, 77).seal(START, &h, &items);
        assert_eq!(kind_of(&other), "wrong key");
        for at in [
            STAMP_AT,
            STAMP_AT + 4,
            STAMP_AT + 12,
            STAMP_AT + 20,
            HEAD_BYTES + 5,
        ] {
            let mut flipped = bytes.clone();
            flipped[at] ^= 1;
            assert_eq!(
                kind_of(&flipped),
                "wrong key",
                "a changed byte at {at} (source, epoch, sequence, start or data) breaks the tag"
            );
        }
        assert_eq!(kind_of(&bytes[..bytes.len() - 1]), "wrong key");
        assert_eq!(kind_of(&bytes[..10]), "malformed");
        let policy = Sealer::in_epoch(&key(), Kind::Policy, 0, 5).seal(
            START,
            &PolicyHeader::default(),
            &[0.5f32; 4],
        );
        assert_eq!(kind_of(&policy), "wrong kind");
        let e = Opener::new(&key())
            .open::<PolicyHeader, f32>(Kind::Rollout, &bytes, &mut Vec::new())
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

    fn stamp(source: u32, epoch: u64, seq: u64) -> Stamp {
        Stamp {
            source,
            epoch,
            seq,
            start: START,
        }
    }

    #[test]
    fn a_stream_takes_each_frame_once_and_a_restarted_sender_from_its_new_epoch_on() {
        let mut s = Streams::default();
        assert_eq!(s.admit(stamp(3, 10, 0)), Ok(Place::New { lost: 0 }));
        assert_eq!(s.admit(stamp(3, 10, 1)), Ok(Place::New { lost: 0 }));
        assert_eq!(s.admit(stamp(3, 10, 1)), Ok(Place::Last));
        assert_eq!(
            s.admit(stamp(3, 10, 0)).map_err(|r| r.kind),
            Err("replayed")
        );
        assert_eq!(s.admit(stamp(3, 10, 4)), Ok(Place::New { lost: 2 }));
        // Another source's stream is its own.
        assert_eq!(s.admit(stamp(4, 10, 0)), Ok(Place::New { lost: 0 }));
        // Source 3's bridge starts again: a new epoch from 0, and the old one is over, even
        // for frames it never sent.
        assert_eq!(s.admit(stamp(3, 11, 0)), Ok(Place::Restarted));
        assert_eq!(s.admit(stamp(3, 11, 1)), Ok(Place::New { lost: 0 }));
        assert_eq!(
            s.admit(stamp(3, 10, 5)).map_err(|r| r.kind),
            Err("replayed")
        );
        assert_eq!(
            s.admit(stamp(3, 10, 0)).map_err(|r| r.kind),
            Err("replayed")
        );
        s.clear();
        assert_eq!(s.admit(stamp(3, 10, 0)), Ok(Place::New { lost: 0 }));
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
            let r = Opener::new(&key()).open::<RolloutHeader, Transition>(Kind::Rollout, &bytes, &mut Vec::new());
            prop_assert!(r.is_err());
        }
    }
}
