//! The terrain kinds, declared once: each kind's name, wire code, model label and colour, and
//! from that one table the three types that name a kind: [`AreaKind`] (where an env lives:
//! a kind's area or the mixed course), [`PolicySlot`] (what a learner fills: the general
//! model or a kind's specialist) and [`Acting`] (what an env acts with).
//!
//! A new kind is one line of the table below, its generator (`crate::terrain` and its
//! settings in `[sim.terrain]`) and its tests; python/lavatube/reader.py names the slots for
//! Python readers (a test keeps it equal to [`PolicySlot::ALL`]).

use super::setting::Setting;
use serde::{Deserialize, Serialize};

macro_rules! terrain_kinds {
    ($(
        $(#[doc = $doc:literal])*
        $kind:ident = $name:literal, code $code:literal, model $model:literal, colour $colour:expr;
    )*) => {
        /// Which area an env lives in: a terrain kind's area (SPEC S1's flat and rough, and
        /// beyond the paper the other kinds of the table), or the mixed course (our extension,
        /// for the switching evaluation), flat ground that crosses other kinds part-way. Env
        /// order is the declaration order: the kinds, then the mixed course.
        #[derive(
            Debug, Clone, Copy, Default, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize,
            Deserialize,
        )]
        #[serde(rename_all = "kebab-case")]
        pub enum AreaKind {
            #[default]
            $($(#[doc = $doc])* $kind,)*
            /// The mixed course (`sim.terrain.mixed-area`).
            Mixed,
        }

        impl AreaKind {
            /// The terrain kinds, in env order (every area but the mixed course).
            pub const KINDS: [AreaKind; [$($code),*].len()] = [$(AreaKind::$kind),*];

            /// Every area, in env order: the kinds, then the mixed course.
            pub const ALL: [AreaKind; [$($code),*].len() + 1] = [$(AreaKind::$kind,)* AreaKind::Mixed];

            /// The wire and CSV code ([`MIXED_CODE`] for the mixed course, which telemetry
            /// never carries: a mixed env reports the ground under the robot).
            pub fn code(self) -> u8 {
                match self {
                    $(AreaKind::$kind => $code,)*
                    AreaKind::Mixed => MIXED_CODE,
                }
            }

            pub fn name(self) -> &'static str {
                match self {
                    $(AreaKind::$kind => $name,)*
                    AreaKind::Mixed => "mixed",
                }
            }

            /// The label of the kind's specialist in reports (SPEC S8's FTM and RTM);
            /// `None` for the mixed course.
            pub fn model(self) -> Option<&'static str> {
                match self {
                    $(AreaKind::$kind => Some($model),)*
                    AreaKind::Mixed => None,
                }
            }

            /// The area's colour in figures and recordings, RGB.
            pub fn colour(self) -> [u8; 3] {
                match self {
                    $(AreaKind::$kind => $colour,)*
                    AreaKind::Mixed => MIXED_COLOUR,
                }
            }
        }

        /// A policy slot of the sim's policy set (DESIGN §5): what a learner fills and an env
        /// acts with: the general model, or a terrain kind's specialist.
        #[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
        #[serde(rename_all = "kebab-case")]
        pub enum PolicySlot {
            General,
            $($kind,)*
        }

        impl PolicySlot {
            /// Every slot, in wire-index order: general, then the kinds' specialists.
            pub const ALL: [PolicySlot; [$($code),*].len() + 1] =
                [PolicySlot::General, $(PolicySlot::$kind),*];

            pub fn name(self) -> &'static str {
                match self {
                    PolicySlot::General => "general",
                    $(PolicySlot::$kind => $name,)*
                }
            }

            /// The process (and shared-memory node) name of the slot's learner.
            pub fn learner_name(self) -> &'static str {
                match self {
                    PolicySlot::General => "learner",
                    $(PolicySlot::$kind => concat!("learner-", $name),)*
                }
            }

            /// The terrain kind a specialist slot is for; `None` for the general slot.
            pub fn kind(self) -> Option<AreaKind> {
                match self {
                    PolicySlot::General => None,
                    $(PolicySlot::$kind => Some(AreaKind::$kind),)*
                }
            }
        }

        /// Which slot an env acts with (DESIGN §5).
        #[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
        #[serde(rename_all = "kebab-case")]
        pub enum Acting {
            General,
            $($kind,)*
            /// The specialist for the estimator's current class, changed only after the
            /// estimate has held for `switch-dwell` ticks (SPEC S8).
            Switch,
            /// A gym client sends every env's actions each tick (`sim.external`); no policy acts.
            External,
        }

        impl Acting {
            /// The slot every env acts with, unless switching.
            pub fn fixed(self) -> Option<PolicySlot> {
                match self {
                    Acting::General => Some(PolicySlot::General),
                    $(Acting::$kind => Some(PolicySlot::$kind),)*
                    Acting::Switch | Acting::External => None,
                }
            }
        }
    };
}

/// The mixed course's code: no ground is of it.
const MIXED_CODE: u8 = 2;

const MIXED_COLOUR: [u8; 3] = [148, 103, 189];

terrain_kinds! {
    /// SPEC S1's flat ground: millimetre micro-relief.
    Flat = "flat", code 0, model "FTM", colour [31, 119, 180];
    /// SPEC S1's rough ground: multi-octave bumps.
    Rough = "rough", code 1, model "RTM", colour [214, 39, 40];
    /// Loose regolith on an incline (`[sim.terrain.slope]`).
    Slope = "slope", code 3, model "STM", colour [140, 86, 75];
    /// Small dense broken rock (`[sim.terrain.gravel]`).
    Gravel = "gravel", code 4, model "GTM", colour [127, 127, 127];
    /// Soft rippled ground the wheels sink in (`[sim.terrain.sand]`); its model is the dune
    /// terrain model.
    Sand = "sand", code 5, model "DTM", colour [219, 186, 92];
}

impl Setting for AreaKind {}
impl Setting for PolicySlot {}
impl Setting for Acting {}

impl PolicySlot {
    /// The slot's index on the wire (`PolicyHeader::slot`, `Transition::slot`).
    pub fn index(self) -> usize {
        self as usize
    }

    /// The slot at a wire index (`PolicySlot::index`); `None` for an index no slot has.
    pub fn from_index(index: u32) -> Option<Self> {
        usize::try_from(index)
            .ok()
            .and_then(|i| Self::ALL.get(i).copied())
    }

    /// Parses a slot name (`general` or a kind's), for command lines.
    pub fn parse(name: &str) -> Result<Self, String> {
        Self::ALL
            .into_iter()
            .find(|s| s.name() == name)
            .ok_or_else(|| format!("unknown policy slot `{name}`: use {}", Self::names()))
    }

    /// Every slot's name, for messages: `general, flat, rough, …`.
    pub fn names() -> String {
        Self::ALL.map(Self::name).join(", ")
    }

    /// The estimator class whose transitions the slot's learner trains on: its kind's code
    /// (`AreaKind::code`; the two-class estimator's class 0, the lowest-mean component, is
    /// flat, and 1 rough); `None`: all.
    pub fn class(self) -> Option<u8> {
        self.kind().map(AreaKind::code)
    }

    /// The specialist for an estimator class, a kind's code (SPEC S8), if there is one.
    pub fn for_class(class: u8) -> Option<Self> {
        Self::ALL
            .into_iter()
            .find(|s| s.kind().is_some_and(|k| k.code() == class))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_kind_has_one_code_name_slot_and_model_of_its_own() {
        let codes: Vec<u8> = AreaKind::ALL.map(AreaKind::code).to_vec();
        assert_eq!(
            codes,
            [0, 1, 3, 4, 5, 2],
            "codes are wire format: never renumber"
        );
        for (i, a) in AreaKind::ALL.iter().enumerate() {
            let before = &AreaKind::ALL[..i];
            assert!(
                before
                    .iter()
                    .all(|b| b.name() != a.name() && b.code() != a.code())
            );
        }
        let models: Vec<_> = AreaKind::KINDS.iter().filter_map(|k| k.model()).collect();
        assert_eq!(models, ["FTM", "RTM", "STM", "GTM", "DTM"]);
        for kind in AreaKind::KINDS {
            let slot = PolicySlot::for_class(kind.code()).expect("a specialist per kind");
            assert_eq!((slot.kind(), slot.name()), (Some(kind), kind.name()));
            assert_eq!(slot.learner_name(), format!("learner-{}", kind.name()));
        }
        assert_eq!(
            PolicySlot::names(),
            "general, flat, rough, slope, gravel, sand"
        );
    }

    #[test]
    fn python_readers_name_the_same_slots() {
        let reader = include_str!("../../../python/lavatube/reader.py");
        let line = reader
            .lines()
            .find(|l| l.starts_with("SLOTS = "))
            .expect("reader.py declares SLOTS");
        let quoted: Vec<String> = PolicySlot::ALL
            .iter()
            .map(|s| format!("\"{}\"", s.name()))
            .collect();
        assert_eq!(line, format!("SLOTS = ({})", quoted.join(", ")));
    }
}
