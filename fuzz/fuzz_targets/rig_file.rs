//! Arbitrary bytes to the rig-file reader (`--rig RIG.json`, written by `rths identify`): a rig
//! file or an error, never a panic; an accepted one holds finite numbers only, was identified at
//! the controller's rate, and gives every run that takes it its compensation (the lead filter, the
//! structure scenarios' corrected lead, the device's FE + ATS and LRX uploads).
#![no_main]
use libfuzzer_sys::fuzz_target;
use rths::link_host::wire::rig_values;
use rths::machinery::identify::RigFile;
use rths_link::ModelKind;

fuzz_target!(|data: &[u8]| {
    let text = String::from_utf8_lossy(data);
    let Ok(rig) = RigFile::from_json(&text) else {
        return;
    };
    let a = &rig.actuator;
    assert!(
        rths_files::rate::check_dt("rig", a.dt_s, rths_core::params::DT_S, "").is_ok(),
        "a rig file identified at another rate was accepted"
    );
    assert!(
        rig.specimen_stiffness_factor.is_finite() && rig.specimen_stiffness_factor > 0.0,
        "specimen_stiffness_factor {} accepted",
        rig.specimen_stiffness_factor
    );
    assert!([a.delay_ms, a.dead_time_ms, a.lag_ms, a.gain]
        .iter()
        .all(|x| x.is_finite()));
    assert!(rig.compensation.ats_initial.iter().all(|x| x.is_finite()));
    if let Err(e) = rig.lead_params() {
        panic!("a validated rig file's lead was refused: {e}");
    }
    if let Err(e) = rths::machinery::structure::rig::from_rig_file_named("fuzz", &rig, "fuzz") {
        panic!("a validated rig file's compensation was refused: {e}");
    }
    for kind in [ModelKind::FeAts, ModelKind::Lrx] {
        match rig_values(&rig, kind, 0.0) {
            Ok(v) => assert!(v.iter().all(|x| x.is_finite())),
            Err(e) => panic!("a validated rig file's {kind:?} upload was refused: {e}"),
        }
    }
});
