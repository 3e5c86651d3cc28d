use super::*;

const HEADER: &str = "env,tick,area,episode,x,y,z,theta_x,theta_y,theta_z,sin_pitch,action_left,action_right,reward,terminated,truncated,success,target_x,target_z";

fn parse(text: &str) -> Result<Vec<TelemetryRow>, TelemetryError> {
    TelemetryReader::new(text.as_bytes(), Path::new("t.csv"))?
        .map(|r| r.map(|(_, row)| row))
        .collect()
}

#[test]
fn columns_come_from_the_struct() {
    assert_eq!(
        TelemetryRow::columns().join(","),
        format!("{HEADER},{}", TelemetryRow::OPTIONAL_COLUMNS.join(","))
    );
}

#[test]
fn the_imu_columns_are_optional_and_swap_in_for_the_true_attitude() {
    let row = "0,0,flat,0,0,0,0,0.1,0.2,0.3,0.0998,0,0,0,false,false,false,0,0";
    let old = parse(&format!("{HEADER}\n{row}\n")).expect("without IMU columns");
    assert!(old[0].imu_sin_pitch.is_nan() && old[0].imu_theta_z.is_nan());
    let new = parse(&format!(
        "{HEADER},imu_theta_x,imu_theta_y,imu_theta_z,imu_sin_pitch\n{row},0.11,0.21,0.31,0.1098\n"
    ))
    .expect("with IMU columns");
    let imu = new[0].with_imu_attitude();
    assert_eq!(
        [imu.theta_x, imu.theta_y, imu.theta_z, imu.sin_pitch],
        [0.11, 0.21, 0.31, 0.1098]
    );
    assert_eq!((imu.env, imu.x, imu.target_z), (0, 0.0, 0.0));
}

#[test]
fn reads_rows_in_any_column_order() {
    let text =
        format!("{HEADER}\n0,5,rough,1,0,0,0,0.1,0,0.2,0.0998,0,0,0,false,false,false,0,0\n");
    let rows = parse(&text).expect("rows");
    assert_eq!(rows.len(), 1);
    assert_eq!(rows[0].area, crate::AreaKind::Rough);
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
fn rows_come_with_their_line() {
    let good = "0,0,flat,0,0,0,0,0,0,0,0,0,0,0,false,false,false,0,0";
    let lines: Vec<u64> = TelemetryReader::new(
        format!("{HEADER}\n{good}\n{good}\n").as_bytes(),
        Path::new("t.csv"),
    )
    .expect("header")
    .map(|r| r.expect("row").0)
    .collect();
    assert_eq!(lines, [2, 3]);
}

#[test]
fn read_csv_returns_the_rows_written() {
    let dir = tempfile::tempdir().expect("tempdir");
    let path = dir.path().join("t.csv");
    let rows = [
        TelemetryRow {
            env: 1,
            tick: 7,
            area: crate::AreaKind::Rough,
            sin_pitch: -0.25,
            success: true,
            ..TelemetryRow::default()
        },
        TelemetryRow::default(),
    ];
    let mut w = csv::Writer::from_path(&path).expect("create");
    for r in &rows {
        w.serialize(r).expect("write");
    }
    w.flush().expect("flush");
    assert_eq!(TelemetryRow::read_csv(&path).expect("read"), rows);
}

#[test]
fn missing_column_names_it() {
    let header = HEADER.replace(",sin_pitch", "");
    let e = parse(&format!("{header}\n")).expect_err("missing");
    assert!(matches!(&e, TelemetryError::MissingColumn { column, .. } if column == "sin_pitch"));
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
        matches!(&e, TelemetryError::Parse { line: 3, field, .. } if field == "area"),
        "{e}"
    );
    let e = parse(&format!("{HEADER}\n0,0,flat\n")).expect_err("short row");
    assert!(
        matches!(e, TelemetryError::Malformed { line: 2, .. }),
        "{e}"
    );
    assert!(matches!(
        TelemetryRow::read_csv(Path::new("/nonexistent/t.csv")),
        Err(TelemetryError::Read { .. })
    ));
}

#[test]
fn the_estimate_and_slot_columns_are_optional_and_empty_without_one() {
    let row = "0,0,flat,0,0,0,0,0.1,0.2,0.3,0.0998,0,0,0,false,false,false,0,0";
    let old = parse(&format!("{HEADER}\n{row}\n")).expect("without the columns");
    assert_eq!((old[0].estimate, old[0].slot), (None, None));
    let new = parse(&format!(
        "{HEADER},estimate,slot\n{row},rough,flat\n{row},,general\n{row},,\n"
    ))
    .expect("with the columns");
    let got: Vec<_> = new.iter().map(|r| (r.estimate, r.slot)).collect();
    use crate::config::PolicySlot;
    assert_eq!(
        got,
        [
            (Some(crate::AreaKind::Rough), Some(PolicySlot::Flat)),
            (None, Some(PolicySlot::General)),
            (None, None)
        ]
    );
}
