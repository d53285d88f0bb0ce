//! The checks that an output can be written, made before the work that fills it: a command that
//! computes for seconds must not end on an unwritable folder, and plotters would report a figure it
//! cannot write only once drawn, as a Debug struct. And standard output itself ([`write_stdout`],
//! the `outln!` and `out!` macros), which the commands and the site print through.

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

/// Exit status of a command whose standard output was closed by its reader (`rths … | head -1`):
/// 0, the reader took what it wanted; the command ends quietly at its next line of output.
pub const EXIT_STDOUT_CLOSED: i32 = 0;

/// Exit status when standard output cannot be written for another reason (a full disk): 1, as any
/// error.
pub const EXIT_STDOUT_FAILED: i32 = 1;

/// Write `args` to standard output (what [`crate::outln!`] and [`crate::out!`] call). A closed
/// pipe ends the process quietly with [`EXIT_STDOUT_CLOSED`]; any other write error is printed to
/// standard error and ends it with [`EXIT_STDOUT_FAILED`]. Never a panic (`println!` panics).
pub fn write_stdout(args: std::fmt::Arguments<'_>) {
    use std::io::Write as _;
    let mut out = std::io::stdout().lock();
    if let Err(e) = out.write_fmt(args).and_then(|()| out.flush()) {
        if e.kind() == std::io::ErrorKind::BrokenPipe {
            std::process::exit(EXIT_STDOUT_CLOSED);
        }
        eprintln!("error: writing to standard output: {e}");
        std::process::exit(EXIT_STDOUT_FAILED);
    }
}

/// `println!` for the commands' output: a closed standard output ends the command quietly
/// ([`write_stdout`](crate::machinery::output::write_stdout)).
#[macro_export]
macro_rules! outln {
    () => {
        $crate::machinery::output::write_stdout(format_args!("\n"))
    };
    ($($arg:tt)*) => {
        $crate::machinery::output::write_stdout(format_args!("{}\n", format_args!($($arg)*)))
    };
}

/// `print!` for the commands' output (see [`outln!`](crate::outln)).
#[macro_export]
macro_rules! out {
    ($($arg:tt)*) => {
        $crate::machinery::output::write_stdout(format_args!($($arg)*))
    };
}
