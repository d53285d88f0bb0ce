//! Bad input never crashes the readers: arbitrary bytes and mutated valid files to the AT2 and CSV
//! ground-motion readers and the model-file loader (the `cargo fuzz` targets in `fuzz/` do the same
//! with coverage guidance; these run in every `cargo test`, no nightly needed). Each must return a
//! value or an error, never panic, and whatever it accepts must be valid.

use proptest::prelude::*;
use rths::machinery::model_file::{ModelFile, ModelKind};
use rths::machinery::motion::{parse_at2, parse_csv};

const LR: &str = include_str!("../data/models/lr.json");
const RNN: &str = include_str!("../data/models/rnn-5.json");
const AT2: &str =
    "PEER\nTEST\nUNITS G\nNPTS=    5, DT= .01000 SEC\n  .1  .2D-1  -.3E-2\n 0.004 -0.005\n";
const CSV: &str = "time_s,accel_g\n0,0.1\n0.01,0.2\n0.02,-0.1\n0.03,0.0\n";

fn check_motion(text: &str) {
    if let Ok(m) = parse_at2(text, "prop") {
        assert!(
            m.validate().is_ok(),
            "AT2 accepted an invalid motion: {text:?}"
        );
    }
    if let Ok(m) = parse_csv(text, "prop") {
        assert!(
            m.validate().is_ok(),
            "CSV accepted an invalid motion: {text:?}"
        );
    }
}

fn check_model(text: &str) {
    if let Ok(m) = ModelFile::from_json(text) {
        assert!(m.validate().is_ok());
        let ok = match m.kind {
            ModelKind::Lr => rths::machinery::models::lr_params(&m).is_ok(),
            ModelKind::Rnn => rths::machinery::models::rnn_params(&m).is_ok(),
            ModelKind::Lrx => rths::machinery::models::lrx_params(&m).is_ok(),
        };
        // A file made at another controller rate is valid but refused to run (issue 27).
        let at_rate = rths_files::rate::check_dt("m", m.dt_s, rths_core::params::DT_S, "").is_ok();
        assert_eq!(
            ok, at_rate,
            "a validated model at the controller's rate was refused (or one at another accepted)"
        );
    }
}

/// `text` with the bytes in `edits` (position, new byte) replaced, as lossy UTF-8.
fn mutate(text: &str, edits: &[(usize, u8)]) -> String {
    let mut b = text.as_bytes().to_vec();
    for &(i, v) in edits {
        let n = b.len();
        if n > 0 {
            b[i % n] = v;
        }
    }
    String::from_utf8_lossy(&b).into_owned()
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(512))]

    #[test]
    fn arbitrary_bytes_never_crash_the_readers(bytes in proptest::collection::vec(any::<u8>(), 0..2048)) {
        let text = String::from_utf8_lossy(&bytes);
        check_motion(&text);
        check_model(&text);
    }

    #[test]
    fn number_soup_never_crashes_the_motion_readers(text in "[0-9eEdD.,;:=+\\- \\t\\r\\nNPTSDTnaif#]{0,600}") {
        check_motion(&text);
        // With a real AT2 header in front, the value section is exercised too.
        check_motion(&format!("a\nb\nc\nNPTS= 20, DT= 0.01\n{text}"));
        check_motion(&format!("time_s,accel_g\n{text}"));
    }

    #[test]
    fn mutated_valid_files_never_crash(edits in proptest::collection::vec((any::<usize>(), any::<u8>()), 1..8)) {
        check_motion(&mutate(AT2, &edits));
        check_motion(&mutate(CSV, &edits));
        check_model(&mutate(LR, &edits));
        check_model(&mutate(RNN, &edits));
    }

    #[test]
    fn truncated_model_files_are_rejected_cleanly(cut in 0usize..4000) {
        let end = cut.min(LR.len());
        if LR.is_char_boundary(end) {
            check_model(&LR[..end]);
        }
    }
}

#[test]
fn the_seeds_are_accepted() {
    assert!(parse_at2(AT2, "seed").is_ok());
    assert!(parse_csv(CSV, "seed").is_ok());
    assert!(ModelFile::from_json(LR).is_ok());
    assert!(ModelFile::from_json(RNN).is_ok());
}

/// Found by `cargo fuzz` (at2 target): a header announcing a huge NPTS made the reader reserve memory
/// for it before reading a value (8.9 GB here; `usize::MAX`-sized counts would abort on capacity
/// overflow). It must be an ordinary count error.
#[test]
fn a_huge_npts_is_a_count_error_not_an_allocation() {
    for npts in ["1111111115", "18446744073709551615", "99999999999999999"] {
        let text = format!("x\ny\nz\n   {npts}  .0050  NPTS, DT\n1 2\n");
        let e = parse_at2(&text, "huge").unwrap_err();
        assert!(e.to_string().contains("NPTS"), "{e}");
    }
}

/// A reduced model file's mode and output counts sized the read-outs' table before anything was
/// checked: 40 000 modes and 100 000 outputs (a 5 MB file) asked for 32 GB and aborted. The counts
/// are now checked against the controller's limits first: a count error naming the limit.
#[test]
fn a_reduced_model_with_huge_counts_is_a_count_error_not_an_allocation() {
    use rths_files::reduced_model_file::{
        ReducedModeEntry, ReducedModelFile, ReducedTraining, StaticEntry, REDUCED_FORMAT,
        REDUCED_VERSION,
    };
    let mode = ReducedModeEntry {
        frequency_hz: 1.0,
        omega_rad_s: std::f64::consts::TAU,
        damping_ratio: 0.02,
        ground_participation: 1.0,
        interface_shape: 1.0,
        output_shape: Vec::new(),
    };
    let zero = StaticEntry {
        ground_mm_per_mm_s2: 0.0,
        force_mm_per_kn: 0.0,
    };
    let file = ReducedModelFile {
        format: REDUCED_FORMAT.into(),
        version: REDUCED_VERSION,
        structure: "huge".into(),
        structure_checksum: "fnv1a64:0".into(),
        dt_s: rths_core::params::DT_S,
        dofs: 1,
        mass_dofs: 1,
        specimen_k_kn_per_mm: 1.0,
        outputs: vec![String::new(); 100_000],
        modes: vec![mode; 40_000],
        interface_static: zero,
        output_static: Vec::new(),
        training: ReducedTraining {
            records: Vec::new(),
            target_nrmse_pct: 1.0,
            error_bound_pct: 1.0,
            per_record: Vec::new(),
            total_modes: 40_000,
            lowest_truncated_hz: None,
            damping_coupling: 0.0,
        },
    };
    let e = file.arrays().unwrap_err().to_string();
    assert!(e.contains("40000 modes") && e.contains("at most 32"), "{e}");
    let few_modes = ReducedModelFile {
        modes: file.modes[..2].to_vec(),
        ..file
    };
    let e = few_modes.arrays().unwrap_err().to_string();
    assert!(
        e.contains("100000 outputs") && e.contains("at most 16"),
        "{e}"
    );
}

/// An imported structure file's equation count sized the condensed model's dense matrices before
/// anything bounded it: 100 000 DOFs with mass (a 4 MB file) asked for 80 GB per matrix and
/// aborted. The count is now checked first: a size error naming the limit.
#[test]
fn an_imported_structure_too_large_to_condense_is_refused_not_allocated() {
    use rths::machinery::imported::file::{
        ImportedFile, ImportedSpecimen, Source, MAX_DENSE_ENTRIES,
    };
    use rths::machinery::imported::DofLabel;
    let n = 100_000;
    let file = ImportedFile {
        format: "rths-structure".into(),
        version: 2,
        kind: "sparse".into(),
        name: "huge".into(),
        description: String::new(),
        units: rths_files::structure_file::Units::MmKn,
        source: Source {
            script: "huge.py".into(),
            checksum: "fnv1a64:0".into(),
        },
        equations: (0..n as u64)
            .map(|node| DofLabel { node, dof: 1 })
            .collect(),
        influence: vec![1.0; n],
        mass: (0..n).map(|i| (i, i, 1.0)).collect(),
        damping: Vec::new(),
        stiffness: (0..n).map(|i| (i, i, 10.0)).collect(),
        specimen: ImportedSpecimen {
            at: DofLabel { node: 0, dof: 1 },
            stiffness_kn_per_mm: 1.0,
        },
        outputs: Vec::new(),
    };
    let e = file.validate().unwrap_err().to_string();
    assert!(
        e.contains("100000 DOFs carry mass") && e.contains(&MAX_DENSE_ENTRIES.to_string()),
        "{e}"
    );
}
