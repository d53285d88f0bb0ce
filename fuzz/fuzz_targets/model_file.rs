//! Arbitrary bytes to the model-file loader: a model or an error, never a panic; an accepted model
//! validates and converts to the controller's parameters.
#![no_main]
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let text = String::from_utf8_lossy(data);
    if let Ok(m) = rths_files::model_file::ModelFile::from_json(&text) {
        assert!(m.validate().is_ok());
        let ok = match m.kind {
            rths_files::model_file::ModelKind::Lr => rths::models::lr_params(&m).is_ok(),
            rths_files::model_file::ModelKind::Rnn => rths::models::rnn_params(&m).is_ok(),
            rths_files::model_file::ModelKind::Lrx => rths::models::lrx_params(&m).is_ok(),
        };
        assert!(ok, "a validated model file was refused by the controller");
    }
});
