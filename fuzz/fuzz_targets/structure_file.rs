//! Arbitrary bytes to the structure-file readers (`--structure FILE.json`): the dense file of
//! `data/structures/` (version 1) and the sparse one `rths import opensees` writes (version 2),
//! picked by the file's header as the commands pick them. A structure or an error, never a panic;
//! an accepted structure has finite matrices and builds the numerical substructure (and, for
//! yielding stories, the nonlinear one) at the controller's step; an imported one condenses to
//! finite matrices whose interface and outputs are among its DOFs.
#![no_main]
use libfuzzer_sys::fuzz_target;
use rths::machinery::imported::file::is_imported;
use rths::machinery::imported::ImportedStructure;
use rths_core::params::DT_S;
use rths_files::structure_file::Structure;

fuzz_target!(|data: &[u8]| {
    let text = String::from_utf8_lossy(data);
    if is_imported(&text) {
        let Ok(s) = ImportedStructure::from_json(&text) else {
            return;
        };
        let (m, c, k) = s.condensed_dense();
        let n = s.mass_dofs();
        assert!(n >= 1 && m.nrows() == n && c.nrows() == n && k.nrows() == n);
        assert!(m
            .iter()
            .chain(c.iter())
            .chain(k.iter())
            .all(|x| x.is_finite()));
        assert!(s.condensed_influence().iter().all(|x| x.is_finite()));
        assert!(s.interface_index() < n);
        assert!(s.output_indices().iter().all(|&i| i < n));
        assert!(s.specimen_stiffness_kn_per_mm().is_finite());
        return;
    }
    let Ok(s) = Structure::from_json(&text) else {
        return;
    };
    assert!(s
        .mass()
        .iter()
        .chain(s.stiffness().iter())
        .chain(s.damping().iter())
        .all(|x| x.is_finite()));
    let (m_e, k_e, c_e) = s.specimen();
    assert!(m_e.is_finite() && k_e.is_finite() && c_e.is_finite());
    assert!(s.specimen_dof() < s.dofs());
    if let Err(e) = s.numerical() {
        panic!("a validated structure's numerical part was refused: {e}");
    }
    if let Err(e) = s.whole() {
        panic!("a validated structure was refused as a whole: {e}");
    }
    if s.story_laws().is_some() {
        if let Err(e) = s.nonlinear_numerical(DT_S) {
            panic!("a validated yielding structure was refused at the controller's step: {e}");
        }
    }
});
