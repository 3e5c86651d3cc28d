use super::*;
use AreaKind::{Flat, Rough};
use PolicySlot::General;

/// Env 0's ticks as (ground, episode, x, estimate, slot), one row each; env 1 drives beside it
/// without an estimate and never counts.
fn rows() -> Vec<TelemetryRow> {
    let g = Some(General);
    let (f, r) = (Some(PolicySlot::Flat), Some(PolicySlot::Rough));
    #[rustfmt::skip]
    let env0 = [
        // Ticks 0-4: the window fills; nothing counts yet.
        (Flat, 0, 0.00, None, g), (Flat, 0, 0.01, None, g), (Flat, 0, 0.02, None, g),
        (Flat, 0, 0.03, None, g), (Flat, 0, 0.04, None, g),
        // 5-6: flat is estimated, within the dwell of 3; 7: it has held 3, FTM acts.
        (Flat, 0, 0.05, Some(Flat), g), (Flat, 0, 0.06, Some(Flat), g),
        (Flat, 0, 0.07, Some(Flat), f),
        // 8: the general model acts against a settled estimate (a disagreement).
        (Flat, 0, 0.08, Some(Flat), g),
        // 9: the robot crosses into rough ground, still on flat's estimate.
        (Rough, 0, 0.09, Some(Flat), f),
        // 10: placed 1 m on (a new leg), no estimate; 11-12: rough within the dwell.
        (Rough, 1, 1.10, None, f), (Rough, 1, 1.11, Some(Rough), f),
        (Rough, 1, 1.12, Some(Rough), f),
        // 13: RTM acts, 4 ticks after the crossing.
        (Rough, 1, 1.13, Some(Rough), r),
        // 14: back on flat ground, left undetected when the recording ends.
        (Flat, 1, 1.14, Some(Rough), r),
    ];
    let mut out = Vec::new();
    for (tick, (area, episode, x, estimate, slot)) in env0.into_iter().enumerate() {
        for env in 0..2 {
            out.push(TelemetryRow {
                env,
                tick: tick as u64,
                area: if env == 0 { area } else { Rough },
                episode,
                x,
                estimate: if env == 0 { estimate } else { None },
                slot,
                ..TelemetryRow::default()
            });
        }
    }
    out
}

#[test]
fn coverage_counts_a_hand_counted_course() {
    let mut counter = Counter::new(|_| 3);
    rows().iter().for_each(|r| counter.see(r));
    let c = counter.finish();
    // Ticks 5-14 count; tick 10 had no estimate.
    assert_eq!(c.ticks, 10);
    assert!((c.with_estimate - 0.9).abs() < 1e-12);
    // Of the 9 with one, 9 (flat read on rough) and 14 (rough read on flat) are wrong.
    assert!((c.estimate_right.expect("counted") - 7.0 / 9.0).abs() < 1e-12);
    assert_eq!(c.right_pct(), "77.8");
    // Settled: 7 and 13 (held 3), 8, 9 and 14 (the estimate's specialist acted the tick
    // before); 8 disagrees.
    assert_eq!(c.settled, 5);
    assert!((c.acting_on_estimate - 0.8).abs() < 1e-12);
    // general → FTM (7) → general (8) → FTM (9) → RTM (13), twice over for env 1 which
    // acted with the same slots; 13 cm driven by each, the placement's metre not.
    assert_eq!(c.switches, 8);
    assert!((c.metres - 2.0 * 0.13).abs() < 1e-9, "{}", c.metres);
    assert!((c.switches_per_100m - 100.0 * 8.0 / 0.26).abs() < 1e-6);
    // Env 1's ground never changed; env 0 crossed into rough (RTM after 4 ticks) and into
    // flat (missed).
    let rough = c.crossings[&Rough];
    assert_eq!((rough.crossings, rough.detected), (1, 1));
    assert!((rough.mean_delay_ticks - 4.0).abs() < 1e-12);
    let flat = c.crossings[&Flat];
    assert_eq!(
        (flat.crossings, flat.detected, flat.mean_delay_ticks),
        (1, 0, 0.0)
    );
    assert_eq!(
        c.crossings_text(0.1).as_deref(),
        Some("flat 0/1 after 0.00 s, rough 1/1 after 0.40 s")
    );
}

#[test]
fn a_longer_leave_dwell_settles_later() {
    // Leaving the general slot takes 4 ticks here: tick 7 (held 3) is not yet settled.
    let mut counter = Counter::new(|s| if s == General { 4 } else { 3 });
    rows().iter().for_each(|r| counter.see(r));
    let c = counter.finish();
    assert_eq!(c.settled, 4);
    assert!((c.acting_on_estimate - 0.75).abs() < 1e-12);
}

#[test]
fn an_older_record_without_live_accuracy_shows_none() {
    let mut counter = Counter::new(|_| 3);
    rows().iter().for_each(|r| counter.see(r));
    let mut json = serde_json::to_value(counter.finish()).expect("json");
    json.as_object_mut()
        .expect("an object")
        .remove("estimate_right");
    let old: Coverage = serde_json::from_value(json).expect("an older record reads");
    assert_eq!(old.estimate_right, None);
    assert_eq!(old.right_pct(), "-");
}
