//! What each of the policy's observation terms is (SPEC S5), by name, unit and frame: the
//! one list that exported models, their metadata and the docs describe the input by.

use crate::OBS_DIM;

/// One term of the observation vector.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ObsTerm {
    pub name: &'static str,
    pub unit: &'static str,
    /// What it is measured in or relative to.
    pub frame: &'static str,
}

const TARGET_FRAME: &str =
    "the robot's body frame: X along the wheel axle, Y up, Z along the chassis";
const EULER: &str = "Unity Euler angles of the chassis in the world, q = Ry·Rx·Rz";

/// The observation vector's terms in order (SPEC S5): the target relative to the robot, its
/// X-Z distance, and cos/sin of the chassis's Euler angles.
pub const OBS_TERMS: [ObsTerm; OBS_DIM] = [
    ObsTerm {
        name: "target_x",
        unit: "m",
        frame: TARGET_FRAME,
    },
    ObsTerm {
        name: "target_y",
        unit: "m",
        frame: TARGET_FRAME,
    },
    ObsTerm {
        name: "target_z",
        unit: "m",
        frame: TARGET_FRAME,
    },
    ObsTerm {
        name: "target_distance_xz",
        unit: "m",
        frame: TARGET_FRAME,
    },
    ObsTerm {
        name: "cos_pitch_x",
        unit: "1",
        frame: EULER,
    },
    ObsTerm {
        name: "sin_pitch_x",
        unit: "1",
        frame: EULER,
    },
    ObsTerm {
        name: "cos_yaw_y",
        unit: "1",
        frame: EULER,
    },
    ObsTerm {
        name: "sin_yaw_y",
        unit: "1",
        frame: EULER,
    },
    ObsTerm {
        name: "cos_roll_z",
        unit: "1",
        frame: EULER,
    },
    ObsTerm {
        name: "sin_roll_z",
        unit: "1",
        frame: EULER,
    },
];

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_term_has_its_own_name() {
        for (i, t) in OBS_TERMS.iter().enumerate() {
            assert!(
                OBS_TERMS[i + 1..].iter().all(|u| u.name != t.name),
                "{}",
                t.name
            );
        }
    }
}
