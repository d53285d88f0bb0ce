//! Running the shipped OpenSees scripts (`scripts/opensees/`, compiled into the binary) with
//! python3 and openseespy, and reading the exporter's Matrix Market files.
//!
//! Python is `RTHS_PYTHON` if set, else `python3`. openseespy 3.7's shared library needs its
//! `openseespylinux/lib` on `LD_LIBRARY_PATH`: [`python_command`] finds that directory next to the
//! installed package (without importing it) and sets the variable for the child.

use std::ffi::OsString;
use std::path::{Path, PathBuf};
use std::process::Command;

use nalgebra_sparse::io::load_coo_from_matrix_market_file;
use rths_files::structure_file::{Units, STRUCTURE_FORMAT};
use serde::Deserialize;

use super::file::{
    DofLabel, ImportedFile, ImportedSpecimen, Source, Triplet, IMPORTED_KIND, IMPORTED_VERSION,
};

/// The exporter (`scripts/opensees/export_model.py`).
pub const EXPORTER: &str = include_str!("../../../scripts/opensees/export_model.py");
/// OpenSees's own transient analysis of a model (`scripts/opensees/transient.py`).
pub const TRANSIENT: &str = include_str!("../../../scripts/opensees/transient.py");
/// The environment variable naming the Python interpreter.
pub const PYTHON_ENV: &str = "RTHS_PYTHON";
/// How to install what the scripts need.
pub const INSTALL_HINT: &str = "python3 and openseespy are needed: install them with `python3 -m venv .venv && .venv/bin/pip install \
     openseespy==3.7.1.2 numpy` and set RTHS_PYTHON=.venv/bin/python (openseespy 3.7.1.2 is the \
     release for Python 3.11; 3.8 needs Python ≥ 3.12)";

/// Why an export failed.
#[derive(Debug, thiserror::Error)]
pub enum ExportError {
    /// Python could not be started.
    #[error("cannot run Python {python:?} ({error}): {INSTALL_HINT}")]
    NoPython {
        /// The interpreter tried.
        python: OsString,
        /// The cause (in the message).
        error: std::io::Error,
    },
    /// openseespy is not installed for that Python.
    #[error("Python {python:?} has no openseespy package: {INSTALL_HINT}")]
    NoOpenSees {
        /// The interpreter.
        python: OsString,
    },
    /// A script failed.
    #[error("{script} failed ({status}): {stderr}")]
    Script {
        /// The script.
        script: &'static str,
        /// Its exit status.
        status: String,
        /// Its last error lines.
        stderr: String,
    },
    /// Reading or writing a file failed.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The cause.
        source: std::io::Error,
    },
    /// The manifest is not the exporter's.
    #[error("{path}: {reason}")]
    Manifest {
        /// The manifest.
        path: PathBuf,
        /// Why.
        reason: String,
    },
    /// A Matrix Market file is refused.
    #[error("{path}: {reason}")]
    MatrixMarket {
        /// The file.
        path: PathBuf,
        /// Why.
        reason: String,
    },
}

/// The interpreter: `RTHS_PYTHON`, else `python3`.
pub fn python() -> OsString {
    std::env::var_os(PYTHON_ENV).unwrap_or_else(|| OsString::from("python3"))
}

/// A command running the Python interpreter with openseespy's library directory on
/// `LD_LIBRARY_PATH`; refused with how to install them when Python or openseespy is missing.
pub fn python_command() -> Result<Command, ExportError> {
    let py = python();
    // Where openseespylinux is, without importing it (importing needs the library path already).
    let probe = Command::new(&py)
        .args([
            "-c",
            "import importlib.util as u\n\
             s = u.find_spec('openseespy')\n\
             l = u.find_spec('openseespylinux')\n\
             print('yes' if s else 'no')\n\
             print(list(l.submodule_search_locations)[0] if l and l.submodule_search_locations else '')",
        ])
        .output()
        .map_err(|error| ExportError::NoPython {
            python: py.clone(),
            error,
        })?;
    let out = String::from_utf8_lossy(&probe.stdout);
    let mut lines = out.lines();
    if !probe.status.success() || lines.next() != Some("yes") {
        return Err(ExportError::NoOpenSees { python: py });
    }
    let mut cmd = Command::new(&py);
    if let Some(pkg) = lines.next().filter(|l| !l.is_empty()) {
        let lib = Path::new(pkg).join("lib");
        if lib.is_dir() {
            let mut path = OsString::from(lib);
            if let Some(old) = std::env::var_os("LD_LIBRARY_PATH").filter(|v| !v.is_empty()) {
                path.push(":");
                path.push(old);
            }
            cmd.env("LD_LIBRARY_PATH", path);
        }
    }
    Ok(cmd)
}

/// Write `text` as `dir/name` and run it with Python and `args`; its stdout on success.
pub fn run_script(
    text: &str,
    name: &'static str,
    dir: &Path,
    args: &[OsString],
) -> Result<String, ExportError> {
    let path = dir.join(name);
    std::fs::write(&path, text).map_err(|source| ExportError::Io {
        path: path.clone(),
        source,
    })?;
    let out = python_command()?
        .arg(&path)
        .args(args)
        .output()
        .map_err(|error| ExportError::NoPython {
            python: python(),
            error,
        })?;
    if !out.status.success() {
        let err = String::from_utf8_lossy(&out.stderr);
        let tail: Vec<&str> = err
            .lines()
            .filter(|l| !l.trim().is_empty() && !l.starts_with("Process 0 Terminating"))
            .collect();
        let keep = tail.len().saturating_sub(6);
        return Err(ExportError::Script {
            script: name,
            status: out.status.to_string(),
            stderr: tail.get(keep..).unwrap_or_default().join(" | "),
        });
    }
    Ok(String::from_utf8_lossy(&out.stdout).into_owned())
}

/// The exporter's `manifest.json`.
#[derive(Debug, Deserialize)]
struct Manifest {
    format: String,
    version: u64,
    units: Units,
    equations: Vec<DofLabel>,
    influence: Vec<f64>,
    matrices: ManifestMatrices,
}

#[derive(Debug, Deserialize)]
struct ManifestMatrices {
    mass: String,
    damping: String,
    stiffness: String,
}

/// The triplets of a Matrix Market file, sorted by (row, column), 0-based.
fn read_mtx(path: &Path, n: usize) -> Result<Vec<Triplet>, ExportError> {
    let coo = load_coo_from_matrix_market_file::<f64, _>(path).map_err(|e| {
        ExportError::MatrixMarket {
            path: path.to_path_buf(),
            reason: e.to_string(),
        }
    })?;
    if coo.nrows() != n || coo.ncols() != n {
        return Err(ExportError::MatrixMarket {
            path: path.to_path_buf(),
            reason: format!("{} × {} for {n} equations", coo.nrows(), coo.ncols()),
        });
    }
    let mut t: Vec<Triplet> = coo.triplet_iter().map(|(i, j, v)| (i, j, *v)).collect();
    t.sort_by_key(|e| (e.0, e.1));
    Ok(t)
}

/// What `rths import opensees` makes of a model.
#[derive(Debug, Clone)]
pub struct ImportRequest {
    /// The model script.
    pub model: PathBuf,
    /// The specimen's DOF.
    pub specimen: DofLabel,
    /// The specimen's stiffness, kN/mm.
    pub specimen_stiffness_kn_per_mm: f64,
    /// The output DOFs.
    pub outputs: Vec<DofLabel>,
    /// The model's units, if not the script's `RTHS_UNITS`.
    pub units: Option<Units>,
}

/// Run the exporter on `req.model` in `dir` (the openseespy model is built there).
pub fn export(req: &ImportRequest, dir: &Path) -> Result<(), ExportError> {
    let mut args: Vec<OsString> = vec![
        req.model.clone().into_os_string(),
        "--out-dir".into(),
        dir.join("export").into_os_string(),
    ];
    if let Some(u) = req.units {
        args.push("--units".into());
        args.push(
            match u {
                Units::Si => "si",
                Units::MmKn => "mm-kn",
            }
            .into(),
        );
    }
    // The exporter runs the model through `transient.py`'s helper, which it imports from beside it.
    let helper = dir.join("transient.py");
    std::fs::write(&helper, TRANSIENT).map_err(|source| ExportError::Io {
        path: helper.clone(),
        source,
    })?;
    run_script(EXPORTER, "export_model.py", dir, &args).map(|_| ())
}

/// Read the exporter's files in `dir` into a structure file (not yet validated).
pub fn read_export(req: &ImportRequest, dir: &Path) -> Result<ImportedFile, ExportError> {
    let out = dir.join("export");
    let manifest_path = out.join("manifest.json");
    let text = std::fs::read_to_string(&manifest_path).map_err(|source| ExportError::Io {
        path: manifest_path.clone(),
        source,
    })?;
    let bad = |reason: String| ExportError::Manifest {
        path: manifest_path.clone(),
        reason,
    };
    let m: Manifest = serde_json::from_str(&text).map_err(|e| bad(e.to_string()))?;
    if m.format != "rths-opensees-export" || m.version != 1 {
        return Err(bad(format!(
            "format {:?} version {} (expected rths-opensees-export 1)",
            m.format, m.version
        )));
    }
    let n = m.equations.len();
    let script_bytes = std::fs::read(&req.model).map_err(|source| ExportError::Io {
        path: req.model.clone(),
        source,
    })?;
    let script = req
        .model
        .file_name()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default();
    let name = req
        .model
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default();
    let mass = read_mtx(&out.join(&m.matrices.mass), n)?;
    let damping = read_mtx(&out.join(&m.matrices.damping), n)?;
    let stiffness = read_mtx(&out.join(&m.matrices.stiffness), n)?;
    Ok(ImportedFile {
        format: STRUCTURE_FORMAT.to_string(),
        version: IMPORTED_VERSION,
        kind: IMPORTED_KIND.to_string(),
        description: format!(
            "The OpenSees model {script} (rths import opensees: its M, C, K over {n} free DOFs); \
             the specimen is {} kN/mm at {}",
            req.specimen_stiffness_kn_per_mm, req.specimen
        ),
        name,
        units: m.units,
        source: Source {
            script,
            checksum: crate::machinery::identify::rig_file::checksum_hex(&script_bytes),
        },
        equations: m.equations,
        influence: m.influence,
        mass,
        damping,
        stiffness,
        specimen: ImportedSpecimen {
            at: req.specimen,
            stiffness_kn_per_mm: req.specimen_stiffness_kn_per_mm,
        },
        outputs: req.outputs.clone(),
    })
}
