//! Arbitrary bytes to the structure-metamodel readers (`rths train meta`'s output, `--model`): the
//! delta-ARX file of a dense structure (`structure-meta`) and the reduced-order model of an imported
//! one (`rths-reduced-model`), picked by the file's tags. A model or an error, never a panic, never
//! an allocation the file's counts size; what is accepted holds finite values at a positive step.
#![no_main]
use libfuzzer_sys::fuzz_target;
use rths_files::reduced_model_file::ReducedModelFile;
use rths_files::structure_meta::MetaFile;

fuzz_target!(|data: &[u8]| {
    let text = String::from_utf8_lossy(data);
    if ReducedModelFile::is_reduced(&text) {
        let Ok(f) = ReducedModelFile::from_json(&text) else {
            return;
        };
        let Ok(a) = f.arrays() else {
            return;
        };
        assert!(
            f.dt_s.is_finite() && f.dt_s > 0.0,
            "dt_s {} accepted",
            f.dt_s
        );
        let s = a.spec();
        assert!(!s.modes.is_empty());
        assert_eq!(s.output_shape.len(), s.modes.len() * f.outputs.len());
        assert!(s.output_shape.iter().all(|x| x.is_finite()));
        assert!(s.specimen_k_kn_per_mm.is_finite());
        // The modes are continuous-time: the controller builds them at its own step.
        let _ = s.params(rths_core::params::DT_S);
        return;
    }
    let Ok(m) = MetaFile::from_json(&text) else {
        return;
    };
    assert!(
        m.dt_s.is_finite() && m.dt_s > 0.0,
        "dt_s {} accepted",
        m.dt_s
    );
    assert!(m.theta.iter().all(|x| x.is_finite()));
    assert!(m.k_corr_kn_per_mm.is_finite());
    assert!(m.params().is_ok());
});
