//! Arbitrary bytes to the model-file loader: a model or an error, never a panic; an accepted model
//! made at the controller's rate converts to the controller's parameters, and one made at another
//! rate is refused for exactly that reason.
#![no_main]
use libfuzzer_sys::fuzz_target;
use rths::machinery::models::ToParamsError;

fuzz_target!(|data: &[u8]| {
    let text = String::from_utf8_lossy(data);
    if let Ok(m) = rths_files::model_file::ModelFile::from_json(&text) {
        assert!(m.validate().is_ok());
        let converted = match m.kind {
            rths_files::model_file::ModelKind::Lr => {
                rths::machinery::models::lr_params(&m).map(|_| ())
            }
            rths_files::model_file::ModelKind::Rnn => {
                rths::machinery::models::rnn_params(&m).map(|_| ())
            }
            rths_files::model_file::ModelKind::Lrx => {
                rths::machinery::models::lrx_params(&m).map(|_| ())
            }
        };
        let same_rate = (m.dt_s - rths_core::params::DT_S).abs()
            <= rths_files::rate::DT_TOLERANCE * rths_core::params::DT_S;
        match converted {
            Ok(()) => assert!(same_rate, "a model made at another rate was accepted"),
            Err(ToParamsError::Rate(_)) => assert!(!same_rate, "a model at this rate was refused"),
            Err(e) => panic!("a validated model file was refused by the controller: {e}"),
        }
    }
});
