//! The Python package's `python/lavatube/layouts.json` against the wire types as the compiler
//! lays them out: iceoryx2 type name, size, alignment and field offsets of every message type,
//! and the constants that come with them (event bits, sizes, the control channel's event id).
//! `python/tests/test_layouts.py` checks the ctypes twins against the same file, so neither
//! side can drift from the other unnoticed.

use common::ipc::CONTROL_SHUTDOWN;
use common::policy::MAX_HIDDEN;
use common::rollout::Transition;
use common::wire::{
    CLASS_UNKNOWN, EVENT_FAULT, EVENT_PLACED, EVENT_SUCCESS, EVENT_TERMINATED, EVENT_TRUNCATED,
    EnvTick, GYM_CLOSE, GYM_OK, GYM_READY, GYM_REFUSED, GYM_RESET, GYM_SEEDED, GYM_STEP,
    GymActHeader, GymEnvStep, GymStepHeader, HostsHeader, PolicyHeader, RolloutHeader,
    SWAP_MESSAGE_BYTES, SWAP_PATH_BYTES, SimHost, SwapReply, SwapRequest, TerrainEstimate,
    TerrainHeader, TickHeader,
};
use common::{ACT_DIM, OBS_DIM};
use iceoryx2::prelude::ZeroCopySend;
use serde_json::{Map, Value, json};
use std::mem::{align_of, offset_of, size_of};
use std::path::Path;

/// The name iceoryx2 compares when a port connects: the type's `#[type_name(...)]`.
fn type_name<T: ZeroCopySend>() -> &'static str {
    // SAFETY: only reads the name; the unsafety is the implementor's promise about layouts.
    unsafe { <T as ZeroCopySend>::type_name() }
}

/// `("Name", {type_name, size, align, fields: [[field, offset], …]})` for a struct, fields in
/// declaration order. The struct pattern names every field, so a field added in Rust stops
/// this test from compiling until it is listed here too.
macro_rules! layout {
    ($t:ident { $($f:ident),+ $(,)? }) => {{
        let _names_every_field = |v: &$t| {
            let $t { $($f: _),+ } = v;
        };
        (
            stringify!($t).to_string(),
            json!({
                "type_name": type_name::<$t>(),
                "size": size_of::<$t>(),
                "align": align_of::<$t>(),
                "fields": [$([stringify!($f), offset_of!($t, $f)]),+],
            }),
        )
    }};
}

fn expected() -> Value {
    let types: Map<String, Value> = [
        layout!(RolloutHeader {
            chunk,
            env_steps,
            steps,
            envs,
            source,
            _reserved
        }),
        layout!(Transition {
            obs,
            action,
            final_obs,
            logprob,
            reward,
            policy_version,
            env,
            terminated,
            truncated,
            success,
            area,
            estimated_class,
            slot,
            _reserved
        }),
        layout!(PolicyHeader {
            version,
            slot,
            obs_dim,
            act_dim,
            n_hidden,
            hidden,
            obs_clip,
            updates,
            env_steps,
            chunks_seen,
            learner,
            write_failures
        }),
        layout!(TickHeader {
            tick,
            env_steps,
            policy_version,
            envs,
            episodes,
            successes,
            sent_ns,
            reach_ticks,
            reach_ticks_sq
        }),
        layout!(EnvTick {
            env,
            area,
            events,
            slot,
            _reserved,
            pos,
            euler,
            sin_pitch,
            reward,
            target,
            imu_euler,
            imu_sin_pitch,
            command
        }),
        layout!(TerrainHeader {
            tick,
            scored,
            correct,
            envs,
            refits
        }),
        layout!(TerrainEstimate {
            env,
            class,
            _reserved,
            posterior,
            window_std,
            window
        }),
        layout!(HostsHeader {
            sent_ns,
            hosts,
            _reserved
        }),
        layout!(SimHost {
            source,
            joined,
            chunks,
            last_chunk,
            env_steps,
            lost,
            steps_per_s,
            bytes_per_s
        }),
        layout!(SwapRequest {
            config_len,
            checkpoint_len,
            slot,
            _reserved,
            config,
            checkpoint
        }),
        layout!(SwapReply { ok, len, message }),
        layout!(GymActHeader {
            request,
            seed,
            command,
            flags
        }),
        layout!(GymStepHeader {
            request,
            tick,
            env_steps,
            envs,
            command,
            status,
            action_limit
        }),
        layout!(GymEnvStep {
            obs,
            final_obs,
            reward,
            episode_steps,
            terminated,
            truncated,
            success,
            area,
            env
        }),
    ]
    .into_iter()
    .collect();
    json!({
        "types": types,
        "constants": {
            "OBS_DIM": OBS_DIM,
            "ACT_DIM": ACT_DIM,
            "MAX_HIDDEN": MAX_HIDDEN,
            "EVENT_TERMINATED": EVENT_TERMINATED,
            "EVENT_TRUNCATED": EVENT_TRUNCATED,
            "EVENT_SUCCESS": EVENT_SUCCESS,
            "EVENT_FAULT": EVENT_FAULT,
            "EVENT_PLACED": EVENT_PLACED,
            "CLASS_UNKNOWN": CLASS_UNKNOWN,
            "SWAP_PATH_BYTES": SWAP_PATH_BYTES,
            "SWAP_MESSAGE_BYTES": SWAP_MESSAGE_BYTES,
            "CONTROL_SHUTDOWN": CONTROL_SHUTDOWN,
            "GYM_READY": GYM_READY,
            "GYM_STEP": GYM_STEP,
            "GYM_RESET": GYM_RESET,
            "GYM_CLOSE": GYM_CLOSE,
            "GYM_SEEDED": GYM_SEEDED,
            "GYM_OK": GYM_OK,
            "GYM_REFUSED": GYM_REFUSED,
        },
    })
}

#[test]
fn python_layouts_json_matches_the_wire_types() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .expect("the workspace");
    let path = root.join("python/lavatube/layouts.json");
    let found: Option<Value> = std::fs::read_to_string(&path)
        .ok()
        .and_then(|text| serde_json::from_str(&text).ok());
    let want = expected();
    assert!(
        found.as_ref() == Some(&want),
        "{} is missing, unreadable or out of date; after updating the ctypes twins in \
         python/lavatube/wire.py, replace it with:\n{}",
        path.display(),
        serde_json::to_string_pretty(&want).expect("JSON")
    );
}
