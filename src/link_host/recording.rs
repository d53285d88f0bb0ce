//! The recording file format (`rths link run/record --out`, read back by `rths report`): optional
//! `# key: value` header lines, the [`CSV_HEADER`], one row per telemetry record.

use std::io::Read;
use std::path::{Path, PathBuf};

use rths_link::Telemetry;

use super::wire::state_name;

/// The most bytes a recording file may hold: 1 GiB, about 14 million rows (an hour of telemetry
/// at every tick of 4096 Hz). A longer file, or one that never ends (`/dev/zero`), is refused
/// before more than this is read.
pub const MAX_RECORDING_BYTES: u64 = 1 << 30;

/// The most bytes a file that a recording's header names (its ground motion) may hold: 64 MiB,
/// far more than any record's AT2 or CSV file. Only a regular file is read: a device or a pipe
/// (`/dev/zero`) is refused.
pub const MAX_NAMED_FILE_BYTES: u64 = 64 << 20;

/// A recording that cannot be read back.
#[derive(Debug, thiserror::Error)]
pub enum RecordingError {
    /// A line is not what the format says.
    #[error("line {line}: {why}")]
    Line {
        /// The line, from 1 (0: the text ended before the CSV header).
        line: usize,
        /// What is wrong with it.
        why: String,
    },
    /// The file could not be read (the caller names it).
    #[error("cannot be read: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// What the OS said.
        source: std::io::Error,
    },
    /// The recording is larger than [`MAX_RECORDING_BYTES`] (the caller names it).
    #[error("holds more than {limit} bytes, the most a recording may hold")]
    TooLarge {
        /// The limit, bytes.
        limit: u64,
    },
    /// A file the header names is larger than [`MAX_NAMED_FILE_BYTES`].
    #[error(
        "the header's `{key}` names {}, which holds more than {limit} bytes, the most it may hold",
        path.display()
    )]
    NamedTooLarge {
        /// The header key.
        key: String,
        /// The file.
        path: PathBuf,
        /// The limit, bytes.
        limit: u64,
    },
    /// A file the header names is not a regular file (a device, a pipe, a folder).
    #[error("the header's `{key}` names {}, which is not a regular file", path.display())]
    NotAFile {
        /// The header key.
        key: String,
        /// The file.
        path: PathBuf,
    },
}

/// What a recording is of: `# key: value` lines before the CSV header (the ground motion as given
/// and its name, the scale, the record's and the model's checksums as the device reported them, the
/// scenario, the structure...), read back by `rths report` to compute the reference.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct RunHeader {
    /// The fields, in order.
    pub fields: Vec<(String, String)>,
}

/// The first header line of a recording with a header.
pub const RECORDING_FORMAT: &str = "rths-recording 1";

impl RunHeader {
    /// Set `key` (replacing an earlier value).
    pub fn set(&mut self, key: &str, value: impl std::fmt::Display) {
        let v = value.to_string().replace(['\n', '\r'], " ");
        match self.fields.iter_mut().find(|(k, _)| k == key) {
            Some(f) => f.1 = v,
            None => self.fields.push((key.to_string(), v)),
        }
    }

    /// The value of `key`.
    pub fn get(&self, key: &str) -> Option<&str> {
        self.fields
            .iter()
            .find(|(k, _)| k == key)
            .map(|(_, v)| v.as_str())
    }

    /// The header lines (`# format: rths-recording 1` first).
    pub fn lines(&self) -> Vec<String> {
        std::iter::once(format!("# format: {RECORDING_FORMAT}"))
            .chain(self.fields.iter().map(|(k, v)| format!("# {k}: {v}")))
            .collect()
    }
}

/// One row of a recording read back.
#[derive(Debug, Clone, PartialEq)]
pub struct RecordingRow {
    /// Record number.
    pub seq: u32,
    /// Tick from the run's start.
    pub tick: u32,
    /// State name ([`state_name`]).
    pub state: String,
    /// Command sent at this tick, mm.
    pub command_mm: f64,
    /// Target produced at this tick, mm.
    pub target_mm: f64,
    /// Measured displacement read at this tick, mm.
    pub measured_mm: f64,
    /// Measured force read at this tick, kN.
    pub force_kn: f64,
}

/// A recording (`rths link run/record --out`) read back.
#[derive(Debug, Clone, PartialEq)]
pub struct Recording {
    /// Its header (empty for a recording without one).
    pub header: RunHeader,
    /// Its rows.
    pub rows: Vec<RecordingRow>,
}

/// Read a recording's text: optional `# key: value` lines, the [`CSV_HEADER`], the rows.
pub fn read_recording(text: &str) -> Result<Recording, RecordingError> {
    let bad = |line: usize, why: String| RecordingError::Line { line, why };
    let mut header = RunHeader::default();
    let mut lines = text.lines().enumerate();
    loop {
        let Some((i, l)) = lines.next() else {
            return Err(bad(0, "no CSV header".into()));
        };
        if let Some(kv) = l.strip_prefix('#') {
            let (k, v) = kv
                .split_once(':')
                .ok_or_else(|| bad(i + 1, format!("not `# key: value`: {l}")))?;
            let (k, v) = (k.trim(), v.trim());
            if k == "format" {
                if v != RECORDING_FORMAT {
                    return Err(bad(i + 1, format!("unknown format `{v}`")));
                }
            } else {
                check_header_value(k, v).map_err(|why| bad(i + 1, why))?;
                header.set(k, v);
            }
            continue;
        }
        if l.trim() != CSV_HEADER {
            return Err(bad(i + 1, format!("expected the header `{CSV_HEADER}`")));
        }
        break;
    }
    let mut rows = Vec::new();
    for (i, l) in lines {
        if l.trim().is_empty() {
            continue;
        }
        let f: Vec<&str> = l.split(',').collect();
        if f.len() != 8 {
            return Err(bad(i + 1, format!("{} fields, expected 8", f.len())));
        }
        let num = |j: usize| -> Result<f64, RecordingError> {
            f[j].trim()
                .parse::<f64>()
                .map_err(|e| bad(i + 1, format!("field {}: {e}", j + 1)))
        };
        let int = |j: usize| -> Result<u32, RecordingError> {
            f[j].trim()
                .parse::<u32>()
                .map_err(|e| bad(i + 1, format!("field {}: {e}", j + 1)))
        };
        // The time is tick × Δt (the report recomputes it), but a row whose time is not a
        // number is not one the writer wrote.
        if !num(2)?.is_finite() {
            return Err(bad(i + 1, "field 3 (time_s) is not finite".into()));
        }
        rows.push(RecordingRow {
            seq: int(0)?,
            tick: int(1)?,
            state: f[3].trim().to_string(),
            command_mm: num(4)?,
            target_mm: num(5)?,
            measured_mm: num(6)?,
            force_kn: num(7)?,
        });
    }
    Ok(Recording { header, rows })
}

/// The header keys `rths link run` writes as one finite number.
const NUMERIC_KEYS: [&str; 6] = [
    "scale",
    "record_samples",
    "record_dt_s",
    "record_ticks",
    "specimen_stiffness_factor",
    "telemetry_every",
];

/// Refuse a header value `rths link run` never writes: a number key that is not one finite
/// number, `limits` that are not three (stroke mm, velocity mm/s, force kN).
fn check_header_value(key: &str, value: &str) -> Result<(), String> {
    let finite = |t: &str| t.parse::<f64>().ok().filter(|x| x.is_finite());
    if NUMERIC_KEYS.contains(&key) && finite(value).is_none() {
        return Err(format!("`{key}: {value}` is not a finite number"));
    }
    if key == "limits" {
        let numbers: Vec<Option<f64>> = value
            .split(',')
            .map(|part| part.split_whitespace().next().and_then(finite))
            .collect();
        if numbers.len() != 3 || numbers.iter().any(Option::is_none) {
            return Err(format!(
                "`limits: {value}` is not three finite numbers (mm, mm/s, kN)"
            ));
        }
    }
    Ok(())
}

/// A sample a clean run cannot hold: the first one that is not finite before the first fault row.
#[derive(Debug, Clone, PartialEq)]
pub struct UncleanSample {
    /// Its row, from 0.
    pub row: usize,
    /// Its tick.
    pub tick: u32,
    /// The channel (`command_mm`, `target_mm`, `measured_mm`, `force_kn`).
    pub channel: &'static str,
    /// Its value.
    pub value: f64,
    /// The row's state.
    pub state: String,
}

/// The first non-finite sample before any fault row, if any. The supervisor stops on a non-finite
/// sample or target, so a row that is still running with one is not what the board read; after a
/// fault the rows record the stop as it happened (a failed DAQ read is NaN) and are kept as they
/// are.
pub fn first_unclean_sample(rows: &[RecordingRow]) -> Option<UncleanSample> {
    rows.iter()
        .take_while(|r| !r.state.starts_with("fault-"))
        .enumerate()
        .find_map(|(row, r)| {
            [
                ("command_mm", r.command_mm),
                ("target_mm", r.target_mm),
                ("measured_mm", r.measured_mm),
                ("force_kn", r.force_kn),
            ]
            .into_iter()
            .find(|(_, v)| !v.is_finite())
            .map(|(channel, value)| UncleanSample {
                row,
                tick: r.tick,
                channel,
                value,
                state: r.state.clone(),
            })
        })
}

/// Read a recording file ([`read_recording`]), at most [`MAX_RECORDING_BYTES`] of it (the caller
/// names the file in its message).
pub fn read_recording_file(path: &Path) -> Result<Recording, RecordingError> {
    read_recording_within(path, MAX_RECORDING_BYTES)
}

/// [`read_recording_file`] with a limit of `limit` bytes.
fn read_recording_within(path: &Path, limit: u64) -> Result<Recording, RecordingError> {
    let io = |source| RecordingError::Io {
        path: path.to_path_buf(),
        source,
    };
    let mut text = String::new();
    std::fs::File::open(path)
        .map_err(io)?
        .take(limit.saturating_add(1))
        .read_to_string(&mut text)
        .map_err(io)?;
    if text.len() as u64 > limit {
        return Err(RecordingError::TooLarge { limit });
    }
    read_recording(&text)
}

/// Check that the file a recording's header names under `key` can be read within a limit: a
/// regular file of at most [`MAX_NAMED_FILE_BYTES`] (a device or a pipe that never ends is
/// refused before a byte of it is read).
pub fn check_named_file(key: &str, path: &Path) -> Result<(), RecordingError> {
    let meta = std::fs::metadata(path).map_err(|source| RecordingError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    if !meta.is_file() {
        return Err(RecordingError::NotAFile {
            key: key.to_string(),
            path: path.to_path_buf(),
        });
    }
    if meta.len() > MAX_NAMED_FILE_BYTES {
        return Err(RecordingError::NamedTooLarge {
            key: key.to_string(),
            path: path.to_path_buf(),
            limit: MAX_NAMED_FILE_BYTES,
        });
    }
    Ok(())
}

/// The CSV header of a recording.
pub const CSV_HEADER: &str = "seq,tick,time_s,state,command_mm,target_mm,measured_mm,force_kn";

/// One CSV row (floats in shortest round-trip form: reading them back gives the same bits).
pub fn csv_row(t: &Telemetry) -> String {
    format!(
        "{},{},{:?},{},{:?},{:?},{:?},{:?}",
        t.seq,
        t.tick,
        t.tick as f64 * rths_core::params::DT_S,
        state_name(t.state),
        t.command_mm,
        t.target_mm,
        t.measured_mm,
        t.force_kn
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_recording_reads_back_and_bad_ones_are_refused() {
        let mut h = RunHeader::default();
        h.set("motion", "el-centro");
        h.set("scale", "0.5");
        h.set("scale", "0.75");
        let mut text = h.lines().join("\n");
        text.push('\n');
        text.push_str(CSV_HEADER);
        text.push_str("\n0,0,0.0,running,1.5,1.25,NaN,0.0\n\n");
        let r = read_recording(&text).unwrap();
        assert_eq!(r.header.get("scale"), Some("0.75"), "set replaces");
        assert_eq!(r.header, h);
        assert_eq!(r.rows.len(), 1);
        assert_eq!((r.rows[0].command_mm, r.rows[0].target_mm), (1.5, 1.25));
        assert!(r.rows[0].measured_mm.is_nan());
        for bad in [
            "",
            "# format: rths-recording 9\n",
            "# no colon\n",
            "seq,tick\n",
            &format!("{CSV_HEADER}\n0,0,0.0,running,1.5\n"),
            &format!("{CSV_HEADER}\n0,x,0.0,running,1.5,0,0,0\n"),
            &format!("{CSV_HEADER}\n0,0,0.0,running,one,0,0,0\n"),
        ] {
            assert!(read_recording(bad).is_err(), "{bad:?}");
        }
    }

    #[test]
    fn a_recording_file_that_never_ends_and_a_named_device_are_refused() {
        let dir = std::env::temp_dir().join(format!("rths-recording-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let small = dir.join("run.csv");
        std::fs::write(&small, format!("{CSV_HEADER}\n0,0,0.0,running,1,1,1,0\n")).unwrap();
        assert_eq!(read_recording_file(&small).unwrap().rows.len(), 1);
        assert!(check_named_file("motion", &small).is_ok());
        let missing = dir.join("missing.csv");
        assert!(matches!(
            read_recording_file(&missing),
            Err(RecordingError::Io { .. })
        ));
        assert!(matches!(
            check_named_file("motion", &dir),
            Err(RecordingError::NotAFile { .. })
        ));
        let zero = Path::new("/dev/zero");
        if zero.exists() {
            let e = check_named_file("motion", zero).unwrap_err();
            assert!(e.to_string().contains("not a regular file"), "{e}");
            // /dev/zero as the recording itself: stopped at the limit (here 1 MiB), not read for
            // ever.
            let e = read_recording_within(zero, 1 << 20).unwrap_err();
            assert!(matches!(e, RecordingError::TooLarge { .. }), "{e}");
        }
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
