//! The checks that an output can be written, made before the work that fills it: a command that
//! computes for seconds must not end on an unwritable folder, and plotters would report a figure it
//! cannot write only once drawn, as a Debug struct.

use std::path::Path;

use anyhow::Context as _;

/// Create `dir` (and its parents) and check that a file can be written in it: the commands that
/// compute for seconds call it first, so an unwritable folder is refused before the work.
pub fn writable_dir(dir: &Path) -> anyhow::Result<()> {
    std::fs::create_dir_all(dir)
        .with_context(|| format!("cannot create the output folder {}", dir.display()))?;
    // Dropped (deleted) at once: only the permission to create a file is checked.
    tempfile::Builder::new()
        .prefix(".rths-write-check")
        .tempfile_in(dir)
        .with_context(|| format!("cannot write in the output folder {}", dir.display()))?;
    Ok(())
}

/// Check that `file` can be written (its folder exists and lets a file be made there, or the file
/// exists and is writable) without changing it, before the work that fills it.
pub fn writable_file(file: &Path) -> anyhow::Result<()> {
    let why = || format!("cannot write {}", file.display());
    if file.is_dir() {
        anyhow::bail!("cannot write {}: it is a folder", file.display());
    }
    if file.exists() {
        std::fs::OpenOptions::new()
            .append(true)
            .open(file)
            .with_context(why)?;
        return Ok(());
    }
    std::fs::OpenOptions::new()
        .write(true)
        .create_new(true)
        .open(file)
        .with_context(why)?;
    std::fs::remove_file(file).with_context(why)?;
    Ok(())
}
