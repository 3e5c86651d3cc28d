//! Reading recorded telemetry for the analysis: `common`'s telemetry CSV reader, plus the
//! checks the analysis needs on top of a well-formed file.
//!
//! With `estimator.signal = "imu"` the IMU filter's columns stand in for the true attitude.
//! Non-finite values are refused in the columns the analysis uses (`sin_pitch`, `theta_z`, or
//! their `imu_` twins): a NaN pitch means a broken recording (or, in the IMU's columns, one
//! made without an IMU), and skipping it silently would shift every rolling window after it.
//! A file with no rows is refused too.

use crate::analysis::AREAS;
use crate::{EstimatorError, Result};
use common::config::AttitudeSource;
use common::telemetry::TelemetryReader;
use common::{AreaKind, TelemetryRow};
use std::io::Read;
use std::path::Path;

/// Reads and checks a telemetry CSV file of flat and rough ground (SPEC S7's two kinds), its
/// attitude taken from `signal`.
pub fn read_telemetry(path: &Path, signal: AttitudeSource) -> Result<Vec<TelemetryRow>> {
    checked(TelemetryReader::open(path)?, path, signal, &AREAS)
}

/// [`read_telemetry`] for ground of every kind (`estimator-proc kinds`).
pub fn read_any_kind(path: &Path, signal: AttitudeSource) -> Result<Vec<TelemetryRow>> {
    checked(TelemetryReader::open(path)?, path, signal, &AreaKind::KINDS)
}

/// Every row of `rows` with its attitude from `signal`, refusing non-finite analysis columns,
/// ground the two-class analysis cannot score, and an empty file; `path` only labels errors.
fn checked<R: Read>(
    rows: TelemetryReader<R>,
    path: &Path,
    signal: AttitudeSource,
    kinds: &[AreaKind],
) -> Result<Vec<TelemetryRow>> {
    let fields = match signal {
        AttitudeSource::Truth => ["sin_pitch", "theta_z"],
        AttitudeSource::Imu => ["imu_sin_pitch", "imu_theta_z"],
    };
    let mut out = Vec::new();
    for r in rows {
        let (line, mut row) = r?;
        if signal == AttitudeSource::Imu {
            if row.imu_sin_pitch.is_nan() {
                return Err(EstimatorError::NoImu {
                    path: path.to_path_buf(),
                    line,
                });
            }
            row = row.with_imu_attitude();
        }
        if !kinds.contains(&row.area) {
            return Err(EstimatorError::UnscoredKind {
                path: path.to_path_buf(),
                line,
                kind: row.area.name(),
            });
        }
        for (field, value) in fields.into_iter().zip([row.sin_pitch, row.theta_z]) {
            if !value.is_finite() {
                return Err(EstimatorError::NonFiniteField {
                    path: path.to_path_buf(),
                    line,
                    field,
                    value,
                });
            }
        }
        out.push(row);
    }
    if out.is_empty() {
        return Err(EstimatorError::Empty {
            path: path.to_path_buf(),
        });
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use common::telemetry::TelemetryError;

    const HEADER: &str = "env,tick,area,episode,x,y,z,theta_x,theta_y,theta_z,sin_pitch,action_left,action_right,reward,terminated,truncated,success,target_x,target_z";

    fn parse(text: &str) -> Result<Vec<TelemetryRow>> {
        let path = Path::new("t.csv");
        checked(
            TelemetryReader::new(text.as_bytes(), path)?,
            path,
            AttitudeSource::Truth,
            &AREAS,
        )
    }

    #[test]
    fn ground_the_two_class_analysis_cannot_score_is_refused_with_its_line() {
        let e = parse(&format!(
            "{HEADER}\n0,0,flat,0,0,0,0,0,0,0,0,0,0,0,false,false,false,0,0\n0,1,slope,0,0,0,0,0,0,0,0,0,0,0,false,false,false,0,0\n"
        ))
        .expect_err("slope");
        assert_eq!(
            e.to_string(),
            "t.csv: line 3 is on `slope` ground; the analysis scores SPEC S7's two kinds, flat and rough (`estimator-proc kinds` scores every kind)"
        );
    }

    #[test]
    fn non_finite_analysis_values_name_line_and_column() {
        let good = "0,0,flat,0,0,0,0,0,0,0,0,0,0,0,false,false,false,0,0";
        let e = parse(&format!(
            "{HEADER}\n{good}\n0,1,flat,0,0,0,0,0,0,0,NaN,0,0,0,false,false,false,0,0\n"
        ))
        .expect_err("nan");
        assert!(
            matches!(
                e,
                EstimatorError::NonFiniteField {
                    line: 3,
                    field: "sin_pitch",
                    ..
                }
            ),
            "{e}"
        );
        let e = parse(&format!(
            "{HEADER}\n0,0,flat,0,0,0,0,0,0,inf,0,0,0,0,false,false,false,0,0\n"
        ))
        .expect_err("inf");
        assert!(
            e.to_string().contains("line 2, column `theta_z` is inf"),
            "{e}"
        );
        assert!(matches!(
            parse(&format!("{HEADER}\n")),
            Err(EstimatorError::Empty { .. })
        ));
    }

    #[test]
    fn the_imu_signal_reads_the_imu_columns_and_names_a_recording_without_them() {
        let path = Path::new("t.csv");
        let read = |text: &str| {
            checked(
                TelemetryReader::new(text.as_bytes(), path)?,
                path,
                AttitudeSource::Imu,
                &AREAS,
            )
        };
        let row = "0,0,flat,0,0,0,0,0.1,0,0.2,0.0998,0,0,0,false,false,false,0,0";
        let e = read(&format!("{HEADER}\n{row}\n")).expect_err("no IMU columns");
        assert!(matches!(e, EstimatorError::NoImu { line: 2, .. }), "{e}");
        let imu = format!("{HEADER},imu_theta_x,imu_theta_y,imu_theta_z,imu_sin_pitch\n");
        let rows = read(&format!("{imu}{row},0.05,0,0.3,0.05\n")).expect("IMU columns");
        assert_eq!((rows[0].sin_pitch, rows[0].theta_z), (0.05, 0.3));
        let e = read(&format!("{imu}{row},0.05,0,inf,0.05\n")).expect_err("inf");
        assert!(e.to_string().contains("column `imu_theta_z` is inf"), "{e}");
    }

    #[test]
    fn reader_errors_pass_through() {
        let e = parse(&format!("{HEADER}\n0,0,flat\n")).expect_err("short row");
        assert!(
            matches!(
                e,
                EstimatorError::Telemetry(TelemetryError::Malformed { line: 2, .. })
            ),
            "{e}"
        );
        assert!(matches!(
            read_telemetry(Path::new("/nonexistent/t.csv"), AttitudeSource::Truth),
            Err(EstimatorError::Telemetry(TelemetryError::Read { .. }))
        ));
    }
}
