//! Reading recorded telemetry for the analysis: `common`'s telemetry CSV reader, plus the
//! checks the analysis needs on top of a well-formed file.
//!
//! Non-finite values are refused in the columns the analysis uses (`sin_pitch`, `theta_z`):
//! a NaN pitch means a broken recording, and skipping it silently would shift every rolling
//! window after it. A file with no rows is refused too.

use crate::{EstimatorError, Result};
use common::TelemetryRow;
use common::telemetry::TelemetryReader;
use std::io::Read;
use std::path::Path;

/// Reads and checks a telemetry CSV file.
pub fn read_telemetry(path: &Path) -> Result<Vec<TelemetryRow>> {
    checked(TelemetryReader::open(path)?, path)
}

/// Every row of `rows`, refusing non-finite analysis columns and an empty file; `path` only
/// labels errors.
fn checked<R: Read>(rows: TelemetryReader<R>, path: &Path) -> Result<Vec<TelemetryRow>> {
    let mut out = Vec::new();
    for r in rows {
        let (line, row) = r?;
        for (field, value) in [("sin_pitch", row.sin_pitch), ("theta_z", row.theta_z)] {
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
        checked(TelemetryReader::new(text.as_bytes(), path)?, path)
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
            read_telemetry(Path::new("/nonexistent/t.csv")),
            Err(EstimatorError::Telemetry(TelemetryError::Read { .. }))
        ));
    }
}
