//! One row of per-tick telemetry, as `sim-proc --telemetry` writes it and the offline
//! analysis reads it, and the one reader of such a CSV. The header is the row's field names
//! (in any order; extra columns are ignored); angles are radians.
//!
//! Every read failure names the file and, for a bad row, its line and column.

use serde::de::{self, Visitor};
use serde::{Deserialize, Serialize};
use std::fs::File;
use std::io::{BufReader, Read};
use std::path::{Path, PathBuf};

/// One env at one decision tick (`Default`: env 0 standing at the origin of flat ground).
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct TelemetryRow {
    /// Env index.
    pub env: u32,
    /// Decision tick of this env since the run started (0-based).
    pub tick: u64,
    /// True terrain under the robot: `flat` or `rough` (on the mixed course, the part it is on).
    pub area: crate::AreaKind,
    /// Episode counter of this env.
    pub episode: u64,
    /// Chassis position, metres (Y up).
    pub x: f64,
    pub y: f64,
    pub z: f64,
    /// Unity-convention Euler angles of the chassis, radians in (-π, π]: pitch about the axle (X),
    /// yaw about up (Y), roll about the body's long axis (Z) (SPEC S2).
    pub theta_x: f64,
    pub theta_y: f64,
    pub theta_z: f64,
    /// sin θx, the classifier's input (SPEC S7).
    pub sin_pitch: f64,
    /// Wheel commands after clipping, rad/s.
    pub action_left: f64,
    pub action_right: f64,
    /// Reward earned on this tick.
    pub reward: f64,
    /// The episode ended in a terminal state on this tick (success or failure).
    pub terminated: bool,
    /// The episode was cut by the time limit or a fault on this tick (bootstrap the value).
    pub truncated: bool,
    /// The episode ended on this tick by reaching its target.
    pub success: bool,
    /// Target position on the ground, metres.
    pub target_x: f64,
    pub target_z: f64,
    /// The IMU's orientation filter's Euler angles, as `theta_*`, and the sin of its θx: the
    /// estimator's signal with `estimator.signal = "imu"`. NaN when the sim ran no IMU, and
    /// in recordings made before these columns existed ([`TelemetryRow::OPTIONAL_COLUMNS`]).
    #[serde(default = "not_recorded")]
    pub imu_theta_x: f64,
    #[serde(default = "not_recorded")]
    pub imu_theta_y: f64,
    #[serde(default = "not_recorded")]
    pub imu_theta_z: f64,
    #[serde(default = "not_recorded")]
    pub imu_sin_pitch: f64,
    /// The terrain kind of the estimate the sim held when it chose this tick's action (the
    /// estimator's newest class); empty before an env's first estimate and without an
    /// estimator.
    #[serde(default)]
    pub estimate: Option<crate::AreaKind>,
    /// The policy slot that chose this tick's action; empty when no policy of the sim's did
    /// (a scripted controller, a gym client).
    #[serde(default)]
    pub slot: Option<crate::config::PolicySlot>,
}

/// A column the recording does not have.
fn not_recorded() -> f64 {
    f64::NAN
}

/// Why a telemetry CSV could not be read.
#[derive(Debug, thiserror::Error)]
pub enum TelemetryError {
    #[error("cannot read {path}: {reason}")]
    Read { path: PathBuf, reason: String },
    #[error("{path}: missing column `{column}` (a telemetry CSV needs the columns: {expected})")]
    MissingColumn {
        path: PathBuf,
        column: String,
        expected: String,
    },
    #[error("{path}: line {line}, column `{field}`: {reason}")]
    Parse {
        path: PathBuf,
        line: u64,
        field: String,
        reason: String,
    },
    #[error("{path}: line {line}: {reason}")]
    Malformed {
        path: PathBuf,
        line: u64,
        reason: String,
    },
}

impl TelemetryRow {
    /// Columns a telemetry CSV may lack; they read as NaN (the IMU's) or empty.
    pub const OPTIONAL_COLUMNS: &[&str] = &[
        "imu_theta_x",
        "imu_theta_y",
        "imu_theta_z",
        "imu_sin_pitch",
        "estimate",
        "slot",
    ];

    /// This row with the IMU filter's attitude in place of the true one (`theta_*` and
    /// `sin_pitch`), for an analysis with `estimator.signal = "imu"`.
    #[must_use]
    pub fn with_imu_attitude(self) -> Self {
        Self {
            theta_x: self.imu_theta_x,
            theta_y: self.imu_theta_y,
            theta_z: self.imu_theta_z,
            sin_pitch: self.imu_sin_pitch,
            ..self
        }
    }

    /// The column names a telemetry CSV must have: the serde field names, read from the
    /// `Deserialize` impl so they can never drift from the struct.
    pub fn columns() -> &'static [&'static str] {
        let mut probe = FieldNames(&[]);
        // The probe always fails after recording the names; the error carries nothing.
        let _ = Self::deserialize(&mut probe);
        probe.0
    }

    /// Every row of the telemetry CSV at `path`, in file order.
    pub fn read_csv(path: &Path) -> Result<Vec<Self>, TelemetryError> {
        TelemetryReader::open(path)?
            .map(|r| r.map(|(_, row)| row))
            .collect()
    }
}

/// A telemetry CSV read one row at a time, each with the line it starts on; the header is
/// checked when the reader is made.
pub struct TelemetryReader<R: Read> {
    path: PathBuf,
    csv: csv::Reader<R>,
    headers: csv::StringRecord,
    record: csv::StringRecord,
}

impl TelemetryReader<BufReader<File>> {
    /// Opens the telemetry CSV at `path`.
    pub fn open(path: &Path) -> Result<Self, TelemetryError> {
        let file = File::open(path).map_err(|e| TelemetryError::Read {
            path: path.to_path_buf(),
            reason: e.to_string(),
        })?;
        Self::new(BufReader::new(file), path)
    }
}

impl<R: Read> TelemetryReader<R> {
    /// Reads telemetry CSV text from `reader`; `path` only labels errors.
    pub fn new(reader: R, path: &Path) -> Result<Self, TelemetryError> {
        let mut csv = csv::ReaderBuilder::new()
            .trim(csv::Trim::All)
            .from_reader(reader);
        let headers = csv
            .headers()
            .map_err(|e| csv_error(path, &csv::StringRecord::new(), None, e, 1))?
            .clone();
        let expected = TelemetryRow::columns();
        if let Some(missing) = expected.iter().find(|c| {
            !TelemetryRow::OPTIONAL_COLUMNS.contains(c) && !headers.iter().any(|h| h == **c)
        }) {
            return Err(TelemetryError::MissingColumn {
                path: path.to_path_buf(),
                column: (*missing).to_string(),
                expected: expected.join(","),
            });
        }
        Ok(Self {
            path: path.to_path_buf(),
            csv,
            headers,
            record: csv::StringRecord::new(),
        })
    }
}

impl<R: Read> Iterator for TelemetryReader<R> {
    /// A row and the line of the file it starts on.
    type Item = Result<(u64, TelemetryRow), TelemetryError>;

    fn next(&mut self) -> Option<Self::Item> {
        match self.csv.read_record(&mut self.record) {
            Err(e) => Some(Err(csv_error(&self.path, &self.headers, None, e, 0))),
            Ok(false) => None,
            Ok(true) => {
                let line = self.record.position().map_or(0, csv::Position::line);
                Some(
                    self.record
                        .deserialize(Some(&self.headers))
                        .map(|row| (line, row))
                        .map_err(|e| {
                            csv_error(&self.path, &self.headers, Some(&self.record), e, line)
                        }),
                )
            }
        }
    }
}

/// A deserializer that only records the field list a struct asks for.
struct FieldNames(&'static [&'static str]);

impl<'de> de::Deserializer<'de> for &mut FieldNames {
    type Error = de::value::Error;

    fn deserialize_any<V: Visitor<'de>>(self, _visitor: V) -> Result<V::Value, Self::Error> {
        Err(de::Error::custom("field-name probe"))
    }

    fn deserialize_struct<V: Visitor<'de>>(
        self,
        _name: &'static str,
        fields: &'static [&'static str],
        _visitor: V,
    ) -> Result<V::Value, Self::Error> {
        self.0 = fields;
        Err(de::Error::custom("field-name probe"))
    }

    serde::forward_to_deserialize_any! {
        bool i8 i16 i32 i64 i128 u8 u16 u32 u64 u128 f32 f64 char str string bytes byte_buf
        option unit unit_struct newtype_struct seq tuple tuple_struct map enum identifier
        ignored_any
    }
}

/// A csv error as ours; `line` is used when the error carries no position.
fn csv_error(
    path: &Path,
    headers: &csv::StringRecord,
    record: Option<&csv::StringRecord>,
    e: csv::Error,
    line: u64,
) -> TelemetryError {
    let line = e.position().map_or(line, csv::Position::line);
    match e.kind() {
        csv::ErrorKind::Deserialize { pos, err } => {
            let reason = err.kind().to_string();
            // csv knows the column of a value it failed to parse, but not of one a serde
            // visitor refused ("unknown variant `lava`"): find the column holding the quoted value.
            let column = err.field().map(|i| i as usize).or_else(|| {
                let quoted = reason.split('`').nth(1)?;
                record?.iter().position(|v| v == quoted)
            });
            TelemetryError::Parse {
                path: path.to_path_buf(),
                line: pos.as_ref().map_or(line, csv::Position::line),
                field: column
                    .and_then(|i| headers.get(i))
                    .unwrap_or("?")
                    .to_string(),
                reason,
            }
        }
        _ => TelemetryError::Malformed {
            path: path.to_path_buf(),
            line,
            reason: e.to_string(),
        },
    }
}

#[cfg(test)]
mod tests;
