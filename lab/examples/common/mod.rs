//! What the lab's studies share: the real chamber log, read as a static log.

use qfa_log::static_log::{read_static_from, AccelUnit, StaticLog, StaticOptions, TimeUnit};

/// The tofupilot IMU thermal-cycle log (`QFA_REAL_LOG`, else the shared folder beside the
/// repository) read with its columns and units; `None`, after a SKIPPED line saying how to
/// point at it, when it is absent.
pub fn real_static_log() -> Option<StaticLog> {
    let path = std::env::var("QFA_REAL_LOG")
        .unwrap_or_else(|_| "../shared/real/tofupilot-imu-thermal-cycle/imu_raw_data.tsv".into());
    let Ok(text) = std::fs::read(&path) else {
        println!("SKIPPED real log: {path} not found; set QFA_REAL_LOG to the tofupilot imu_raw_data.tsv");
        return None;
    };
    let opts = StaticOptions {
        columns: "time=timestamp,temp=imu.temperature,ax=imu.acc.x,ay=imu.acc.y,az=imu.acc.z".parse().unwrap(),
        time_unit: Some(TimeUnit::Us),
        accel_unit: Some(AccelUnit::Mps2),
        ..Default::default()
    };
    Some(read_static_from(&text[..], &opts).expect("the real log reads"))
}
