//! Reading recorded telemetry: a CSV whose header is [`TelemetryRow`]'s field names (in any
//! order; extra columns are ignored), one row per env and tick.
//!
//! Every failure names the file, the line and the column. Non-finite values are refused in
//! the columns the analysis uses (`sin_pitch`, `theta_z`): a NaN pitch means a broken
//! recording, and skipping it silently would shift every rolling window after it.

use crate::{EstimatorError, Result};
use common::TelemetryRow;
use serde::Deserialize;
use serde::de::{self, Visitor};
use std::io::Read;
use std::path::Path;

/// Reads and checks a telemetry CSV file.
pub fn read_telemetry(path: &Path) -> Result<Vec<TelemetryRow>> {
    let file = std::fs::File::open(path).map_err(|e| EstimatorError::Read {
        path: path.to_path_buf(),
        reason: e.to_string(),
    })?;
    parse_telemetry(std::io::BufReader::new(file), path)
}

/// Parses telemetry CSV text from `reader`; `path` only labels errors.
pub fn parse_telemetry<R: Read>(reader: R, path: &Path) -> Result<Vec<TelemetryRow>> {
    let mut rdr = csv::ReaderBuilder::new()
        .trim(csv::Trim::All)
        .from_reader(reader);
    let headers = rdr
        .headers()
        .map_err(|e| csv_error(path, &csv::StringRecord::new(), None, e, 1))?
        .clone();
    let expected = telemetry_columns();
    if let Some(missing) = expected.iter().find(|c| !headers.iter().any(|h| h == **c)) {
        return Err(EstimatorError::MissingColumn {
            path: path.to_path_buf(),
            column: (*missing).to_string(),
            expected: expected.join(","),
        });
    }
    let mut rows = Vec::new();
    let mut record = csv::StringRecord::new();
    while rdr
        .read_record(&mut record)
        .map_err(|e| csv_error(path, &headers, None, e, 0))?
    {
        let line = record.position().map_or(0, |p| p.line());
        let row: TelemetryRow = record
            .deserialize(Some(&headers))
            .map_err(|e| csv_error(path, &headers, Some(&record), e, line))?;
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
        rows.push(row);
    }
    if rows.is_empty() {
        return Err(EstimatorError::Empty {
            path: path.to_path_buf(),
        });
    }
    Ok(rows)
}

/// The column names a telemetry CSV must have: [`TelemetryRow`]'s serde field names, read from
/// its `Deserialize` impl so they can never drift from the struct.
pub fn telemetry_columns() -> &'static [&'static str] {
    let mut probe = FieldNames(&[]);
    // The probe always fails after recording the names; the error carries nothing.
    let _ = TelemetryRow::deserialize(&mut probe);
    probe.0
}

/// A deserializer that only records the field list a struct asks for.
struct FieldNames(&'static [&'static str]);

impl<'de> de::Deserializer<'de> for &mut FieldNames {
    type Error = de::value::Error;

    fn deserialize_any<V: Visitor<'de>>(
        self,
        _visitor: V,
    ) -> std::result::Result<V::Value, Self::Error> {
        Err(de::Error::custom("field-name probe"))
    }

    fn deserialize_struct<V: Visitor<'de>>(
        self,
        _name: &'static str,
        fields: &'static [&'static str],
        _visitor: V,
    ) -> std::result::Result<V::Value, Self::Error> {
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
) -> EstimatorError {
    let line = e.position().map_or(line, |p| p.line());
    match e.kind() {
        csv::ErrorKind::Deserialize { pos, err } => {
            let reason = err.kind().to_string();
            // csv knows the column of a value it failed to parse, but not of one a serde
            // visitor refused ("unknown variant `lava`"): find the column holding the quoted value.
            let column = err.field().map(|i| i as usize).or_else(|| {
                let quoted = reason.split('`').nth(1)?;
                record?.iter().position(|v| v == quoted)
            });
            EstimatorError::Parse {
                path: path.to_path_buf(),
                line: pos.as_ref().map_or(line, |p| p.line()),
                field: column
                    .and_then(|i| headers.get(i))
                    .unwrap_or("?")
                    .to_string(),
                reason,
            }
        }
        _ => EstimatorError::Malformed {
            path: path.to_path_buf(),
            line,
            reason: e.to_string(),
        },
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const HEADER: &str = "env,tick,area,episode,x,y,z,theta_x,theta_y,theta_z,sin_pitch,action_left,action_right,reward,terminated,truncated,success,target_x,target_z";

    fn parse(text: &str) -> Result<Vec<TelemetryRow>> {
        parse_telemetry(text.as_bytes(), Path::new("t.csv"))
    }

    #[test]
    fn columns_come_from_the_struct() {
        assert_eq!(telemetry_columns().join(","), HEADER);
    }

    #[test]
    fn reads_rows_in_any_column_order() {
        let text =
            format!("{HEADER}\n0,5,rough,1,0,0,0,0.1,0,0.2,0.0998,0,0,0,false,false,false,0,0\n");
        let rows = parse(&text).expect("rows");
        assert_eq!(rows.len(), 1);
        assert_eq!(rows[0].area, common::AreaKind::Rough);
        assert_eq!(rows[0].tick, 5);
        let mut cols: Vec<&str> = HEADER.split(',').collect();
        cols.reverse();
        let vals: Vec<&str> = "0,5,flat,1,0,0,0,0.1,0,0.2,0.0998,0,0,0,false,false,false,0,0"
            .split(',')
            .rev()
            .collect();
        let rows = parse(&format!("{}\n{}\n", cols.join(","), vals.join(","))).expect("reversed");
        assert_eq!(rows[0].sin_pitch, 0.0998);
    }

    #[test]
    fn missing_column_names_it() {
        let header = HEADER.replace(",sin_pitch", "");
        let e = parse(&format!("{header}\n")).expect_err("missing");
        assert!(
            matches!(&e, EstimatorError::MissingColumn { column, .. } if column == "sin_pitch")
        );
        assert!(
            e.to_string()
                .starts_with("t.csv: missing column `sin_pitch`"),
            "{e}"
        );
    }

    #[test]
    fn bad_values_name_line_and_column() {
        let good = "0,0,flat,0,0,0,0,0,0,0,0,0,0,0,false,false,false,0,0";
        let e = parse(&format!(
            "{HEADER}\n{good}\n0,1,lava,0,0,0,0,0,0,0,0,0,0,0,false,false,false,0,0\n"
        ))
        .expect_err("bad area");
        assert!(
            matches!(&e, EstimatorError::Parse { line: 3, field, .. } if field == "area"),
            "{e}"
        );
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
        let e = parse(&format!("{HEADER}\n0,0,flat\n")).expect_err("short row");
        assert!(
            matches!(e, EstimatorError::Malformed { line: 2, .. }),
            "{e}"
        );
        assert!(matches!(
            parse(&format!("{HEADER}\n")),
            Err(EstimatorError::Empty { .. })
        ));
        assert!(matches!(
            read_telemetry(Path::new("/nonexistent/t.csv")),
            Err(EstimatorError::Read { .. })
        ));
    }
}
