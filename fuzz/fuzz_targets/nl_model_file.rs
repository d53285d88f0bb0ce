//! Arbitrary bytes to the nonlinear (modal-hysteretic) model reader (`--model nl-S.json`, written
//! by `rths train nonlinear`): a model or an error, never a panic; an accepted model made at the
//! controller's rate builds the core's parameters at the controller's step, as `nl-online` does.
#![no_main]
use libfuzzer_sys::fuzz_target;
use rths_files::nl_model_file::NlModelFile;

fuzz_target!(|data: &[u8]| {
    let text = String::from_utf8_lossy(data);
    let Ok(m) = NlModelFile::from_json(&text) else {
        return;
    };
    assert!(
        m.dt_s.is_finite() && m.dt_s > 0.0,
        "dt_s {} accepted",
        m.dt_s
    );
    if rths::machinery::structure::model::check_rate(&m).is_ok() {
        if let Err(e) = m.params(rths_core::params::DT_S) {
            panic!("a validated model at the controller's rate was refused at its step: {e}");
        }
    }
});
