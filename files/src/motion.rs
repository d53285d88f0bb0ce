//! Ground-motion records: PEER AT2 and two-column CSV readers, the four shipped records (embedded in
//! the binary, so it runs from any directory), scaling and resampling to the controller step.
//!
//! Records are stored as read: acceleration in **g** at `t = k·dt_s`, `k = 0..n`. The code works in
//! mm/s² ([`GroundMotion::resample_mm_s2`] converts with [`rths_core::params::G_MM_S2`]).
//!
//! Accepted formats:
//! - **AT2** (PEER): lines 1–3 free text; line 4 holds `NPTS` and `DT` as `NPTS=  4000, DT= .01000 SEC`
//!   or `NPTS= 7945  DT= .0050` (comma optional, `=` or `:`, any case; also the older
//!   `7945 .0050 NPTS, DT` layout); then the values in g, any
//!   number per line, separated by blanks or commas, read in row-major order. LF or CRLF.
//! - **CSV**: two columns `time_s, accel_g` (comma, semicolon or tab separated), an optional header
//!   line, `#` comment lines. Time must increase uniformly: every step within
//!   [`CSV_DT_TOLERANCE`] (1%) of the median step. Times are taken relative to the first row.
//!
//! Limits (every reader, checked before the samples are stored or resampled, so a corrupt header
//! or a typo in a time column cannot ask for gigabytes): a file of at most [`MAX_RECORD_FILE_BYTES`],
//! at most [`MAX_RECORD_SAMPLES`] samples, a duration of at most [`MAX_RECORD_DURATION_S`] and every
//! value within ±[`MAX_RECORD_ACCEL_G`]. [`GroundMotion::validate`] checks the same limits on a
//! record built in code (or scaled).

use std::path::{Path, PathBuf};

use rths_core::motion::Record;

/// Relative tolerance on the time step of a CSV record: every step must be within 1% of the median
/// step; the record's step is then the mean `(t_last − t_first)/(n − 1)`. Loose enough for times printed with few decimals, tight enough
/// to reject a record with a dropped or duplicated sample.
pub const CSV_DT_TOLERANCE: f64 = 0.01;

/// Largest record file read, bytes (64 MiB: ten minutes at 4096 Hz in the most verbose AT2 text
/// fits; a file that never ends, such as `/dev/zero`, is refused at this size).
pub const MAX_RECORD_FILE_BYTES: u64 = 64 << 20;

/// Most samples in one record (2^22: more than [`MAX_RECORD_DURATION_S`] at 4096 Hz).
pub const MAX_RECORD_SAMPLES: usize = 1 << 22;

/// Longest record, s (time of the last sample): ten minutes, longer than any earthquake record a
/// lab runs, and the histories of a run at 4096 Hz stay in tens of MB.
pub const MAX_RECORD_DURATION_S: f64 = 600.0;

/// Largest ground acceleration accepted, g (the strongest records ever measured peak near 4 g; a
/// value beyond this is a unit mistake, such as a record in cm/s² read as g).
pub const MAX_RECORD_ACCEL_G: f64 = 20.0;

/// A ground-motion acceleration record sampled uniformly: `accel_g[k]` is the acceleration in g at
/// `t = k·dt_s`.
#[derive(Debug, Clone, PartialEq)]
pub struct GroundMotion {
    /// Record name (the embedded name, or the file stem).
    pub name: String,
    /// Sampling interval, s.
    pub dt_s: f64,
    /// Ground acceleration, g.
    pub accel_g: Vec<f64>,
}

/// Why a ground-motion record could not be read. Line numbers are 1-based lines of the file.
#[derive(Debug, thiserror::Error)]
pub enum MotionError {
    /// The file holds nothing but whitespace.
    #[error("the file is empty")]
    Empty,
    /// An AT2 file ends before its header does (4 lines: 3 text lines, then NPTS and DT).
    #[error("line {lines}: the AT2 header needs 4 lines (3 text lines, then NPTS and DT), the file has {lines}")]
    ShortHeader {
        /// Lines in the file.
        lines: usize,
    },
    /// The AT2 header line has no `NPTS=` count.
    #[error("line {line}: no `NPTS=` point count in the AT2 header")]
    MissingNpts {
        /// Line number.
        line: usize,
    },
    /// The AT2 header line has no `DT=` time step.
    #[error("line {line}: no `DT=` time step in the AT2 header")]
    MissingDt {
        /// Line number.
        line: usize,
    },
    /// The AT2 header gives `NPTS= 0`.
    #[error("line {line}: NPTS is 0")]
    ZeroNpts {
        /// Line number.
        line: usize,
    },
    /// The time step is not a finite positive number (AT2 header; `line` 0 for a CSV record whose
    /// step is inferred from its times, or for [`GroundMotion::validate`]).
    #[error("line {line}: time step {dt_s} s is not a finite positive number")]
    BadDt {
        /// Line number (0 if not from one line).
        line: usize,
        /// The offending step, s.
        dt_s: f64,
    },
    /// A value is not a number.
    #[error("line {line}: `{token}` is not a number")]
    NotNumeric {
        /// Line number.
        line: usize,
        /// The offending text.
        token: String,
    },
    /// A value is NaN or infinite.
    #[error("line {line}: value is not finite (NaN or infinity)")]
    NonFinite {
        /// Line number (0 for [`GroundMotion::validate`]).
        line: usize,
    },
    /// The number of values differs from the header's NPTS.
    #[error("the header says NPTS = {expected} but the file holds {found} values")]
    PointCount {
        /// NPTS from the header.
        expected: usize,
        /// Values found after the header.
        found: usize,
    },
    /// There are no acceleration values at all (e.g. a CSV with a header only).
    #[error("no acceleration values in the file")]
    NoData,
    /// A CSV record needs at least two rows to define its time step.
    #[error("a CSV record needs at least 2 rows to define its time step, found {rows}")]
    TooFewRows {
        /// Data rows found.
        rows: usize,
    },
    /// A CSV row does not have exactly two fields (time, acceleration).
    #[error("line {line}: expected 2 columns (time_s, accel_g), found {found}")]
    ColumnCount {
        /// Line number.
        line: usize,
        /// Fields found.
        found: usize,
    },
    /// CSV time does not increase.
    #[error("line {line}: time {time_s} s does not increase (previous {previous_s} s)")]
    NonMonotonicTime {
        /// Line number.
        line: usize,
        /// Time on this line, s.
        time_s: f64,
        /// Time on the previous data line, s.
        previous_s: f64,
    },
    /// A CSV time step differs from the median step by more than [`CSV_DT_TOLERANCE`].
    #[error(
        "line {line}: time step {step_s} s differs from the median step {median_step_s} s by more \
         than 1% (the record must be sampled uniformly)"
    )]
    NonUniformTime {
        /// Line number.
        line: usize,
        /// The step ending on this line, s.
        step_s: f64,
        /// The median step of the record, s.
        median_step_s: f64,
    },
    /// The file is larger than [`MAX_RECORD_FILE_BYTES`].
    #[error("the file is larger than the {limit_bytes}-byte limit of a record file")]
    FileTooLarge {
        /// The limit, bytes.
        limit_bytes: u64,
    },
    /// More samples than [`MAX_RECORD_SAMPLES`].
    #[error("line {line}: {samples} samples (NPTS or rows), more than the limit of {limit} samples per record")]
    TooManySamples {
        /// Line number (the AT2 header, or the CSV row past the limit; 0 for `validate`).
        line: usize,
        /// Samples in (or announced by) the file.
        samples: usize,
        /// [`MAX_RECORD_SAMPLES`].
        limit: usize,
    },
    /// A duration beyond [`MAX_RECORD_DURATION_S`].
    #[error(
        "line {line}: the record lasts {duration_s:.6e} s, longer than the limit of {limit_s} s \
         (check the time step and the time column's units)"
    )]
    TooLong {
        /// Line number (the AT2 header, or the CSV's last row; 0 for `validate`).
        line: usize,
        /// Duration `(n − 1)·dt_s`, s.
        duration_s: f64,
        /// [`MAX_RECORD_DURATION_S`].
        limit_s: f64,
    },
    /// An acceleration beyond ±[`MAX_RECORD_ACCEL_G`].
    #[error(
        "line {line}: acceleration {value_g:.6e} g is beyond the limit of ±{limit_g} g (is the \
         record in g?)"
    )]
    AccelOutOfRange {
        /// Line number (0 for `validate`).
        line: usize,
        /// The value, g.
        value_g: f64,
        /// [`MAX_RECORD_ACCEL_G`].
        limit_g: f64,
    },
    /// No embedded record has this name.
    #[error("no embedded ground motion named `{name}` (known: {known})")]
    UnknownRecord {
        /// The name asked for.
        name: String,
        /// The known names, comma-separated.
        known: String,
    },
    /// The file could not be read.
    #[error("cannot read {path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The underlying error.
        source: std::io::Error,
    },
}

/// The shipped records: (name, file stem, AT2 text). Names are what [`GroundMotion::embedded`] and
/// `rths analyze --motion` accept (file stems too).
const EMBEDDED: [(&str, &str, &str); 4] = [
    (
        "el-centro",
        "IELC180",
        include_str!("../../data/ground_motions/IELC180.AT2"),
    ),
    (
        "northridge",
        "RSN1044_NORTHR_NWH360",
        include_str!("../../data/ground_motions/RSN1044_NORTHR_NWH360.AT2"),
    ),
    (
        "loma-prieta",
        "RSN766_LOMAP_G02000",
        include_str!("../../data/ground_motions/RSN766_LOMAP_G02000.AT2"),
    ),
    (
        "kobe",
        "TAK000",
        include_str!("../../data/ground_motions/TAK000.AT2"),
    ),
];

const EMBEDDED_NAMES: [&str; 4] = ["el-centro", "northridge", "loma-prieta", "kobe"];

impl GroundMotion {
    /// The 1940 El Centro NS record (`IELC180.AT2`, 4000 points at 0.01 s, PGA 0.313 g), embedded.
    ///
    /// The embedded text is fixed at build time and its parse is covered by tests, so this cannot
    /// fail in practice; should it ever, the result is an *empty* record (whose name says why), which
    /// every analysis rejects with an error rather than a panic. Use [`Self::try_el_centro`] to see
    /// the error itself.
    pub fn el_centro() -> GroundMotion {
        Self::try_el_centro().unwrap_or_else(|e| GroundMotion {
            name: format!("el-centro (embedded record unreadable: {e})"),
            dt_s: 0.01,
            accel_g: Vec::new(),
        })
    }

    /// The 1940 El Centro NS record, with the parse error should the embedded text be unreadable.
    pub fn try_el_centro() -> Result<GroundMotion, MotionError> {
        Self::try_embedded("el-centro")
    }

    /// A shipped record by name (see [`Self::embedded_names`]; the file stem such as `IELC180`, with
    /// or without `.AT2`, works too; any case). `None` for an unknown name.
    pub fn embedded(name: &str) -> Option<GroundMotion> {
        Self::try_embedded(name).ok()
    }

    /// A shipped record by name, or why not ([`MotionError::UnknownRecord`], or a parse error).
    pub fn try_embedded(name: &str) -> Result<GroundMotion, MotionError> {
        let key = name.trim();
        let key = key
            .strip_suffix(".AT2")
            .or_else(|| key.strip_suffix(".at2"))
            .unwrap_or(key);
        EMBEDDED
            .iter()
            .find(|(n, stem, _)| n.eq_ignore_ascii_case(key) || stem.eq_ignore_ascii_case(key))
            .ok_or_else(|| MotionError::UnknownRecord {
                name: name.to_string(),
                known: EMBEDDED_NAMES.join(", "),
            })
            .and_then(|(n, _, text)| parse_at2(text, n))
    }

    /// Names of the shipped records: `el-centro`, `northridge`, `loma-prieta`, `kobe`.
    pub fn embedded_names() -> &'static [&'static str] {
        &EMBEDDED_NAMES
    }

    /// Read a record file: `.at2` (any case) as AT2, `.csv` as CSV; any other extension is sniffed
    /// (AT2 if one of its first 4 lines mentions `NPTS`). The name is the file stem.
    pub fn from_path(path: &Path) -> Result<GroundMotion, MotionError> {
        let text = read_bounded(path)?;
        let name = path
            .file_stem()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_else(|| "record".to_string());
        let ext = path
            .extension()
            .map(|e| e.to_string_lossy().to_ascii_lowercase());
        match ext.as_deref() {
            Some("at2") => parse_at2(&text, &name),
            Some("csv") => parse_csv(&text, &name),
            _ if looks_like_at2(&text) => parse_at2(&text, &name),
            _ => parse_csv(&text, &name),
        }
    }

    /// The same record with every acceleration multiplied by `factor`; the name gains ` ×factor`
    /// unless the factor is 1.
    pub fn scaled(&self, factor: f64) -> GroundMotion {
        GroundMotion {
            name: if factor == 1.0 {
                self.name.clone()
            } else {
                format!("{} ×{factor}", self.name)
            },
            dt_s: self.dt_s,
            accel_g: self.accel_g.iter().map(|a| a * factor).collect(),
        }
    }

    /// Duration `(n − 1)·dt_s`, s (time of the last sample; 0 for fewer than two samples).
    pub fn duration_s(&self) -> f64 {
        self.accel_g.len().saturating_sub(1) as f64 * self.dt_s
    }

    /// Peak ground acceleration `max |a|`, g.
    pub fn pga_g(&self) -> f64 {
        self.accel_g.iter().fold(0.0_f64, |m, a| m.max(a.abs()))
    }

    /// Check the invariants the readers guarantee (the fields are public): a finite positive step,
    /// at least one sample, all finite.
    pub fn validate(&self) -> Result<(), MotionError> {
        if !(self.dt_s.is_finite() && self.dt_s > 0.0) {
            return Err(MotionError::BadDt {
                line: 0,
                dt_s: self.dt_s,
            });
        }
        if self.accel_g.is_empty() {
            return Err(MotionError::NoData);
        }
        if self.accel_g.iter().any(|a| !a.is_finite()) {
            return Err(MotionError::NonFinite { line: 0 });
        }
        check_samples(self.accel_g.len(), 0)?;
        check_duration(self.duration_s(), 0)?;
        for a in &self.accel_g {
            check_accel(*a, 0)?;
        }
        Ok(())
    }

    /// Ground acceleration in mm/s² at `t = k·dt_s`, `k = 0..=floor(duration/dt_s)`, by linear
    /// interpolation between the record's samples. Empty if `dt_s` is not finite and positive or the
    /// record is empty or has a bad step.
    ///
    /// The interpolation and the tick count are `rths_core::motion::Record`'s, the ones the
    /// firmware runs, so host and MCU see the same ü_g bit for bit.
    pub fn resample_mm_s2(&self, dt_s: f64) -> Vec<f64> {
        let record = self.record();
        (0..record.ticks(dt_s))
            .map(|k| record.accel_mm_s2(k, dt_s))
            .collect()
    }

    /// The samples as a `no_std` [`Record`] (what the interpolation works on).
    pub fn record(&self) -> Record<'_> {
        Record::new(&self.accel_g, self.dt_s)
    }

    /// The record as AT2 text (values in shortest round-trip form, 5 per line, LF).
    pub fn to_at2(&self) -> String {
        let mut s = format!(
            "RTHS GROUND MOTION RECORD\n{}\nACCELERATION TIME HISTORY IN UNITS OF G\nNPTS= {}, DT= {} SEC\n",
            self.name.replace(['\n', '\r'], " "),
            self.accel_g.len(),
            self.dt_s
        );
        for row in self.accel_g.chunks(5) {
            let line: Vec<String> = row.iter().map(|a| format!("{a:>16e}")).collect();
            s.push_str(&line.join(" "));
            s.push('\n');
        }
        s
    }

    /// The record as two-column CSV text with a `time_s,accel_g` header.
    pub fn to_csv(&self) -> String {
        let mut s = String::from("time_s,accel_g\n");
        for (k, a) in self.accel_g.iter().enumerate() {
            s.push_str(&format!("{},{a:e}\n", k as f64 * self.dt_s));
        }
        s
    }
}

/// The text of a record file, refusing one larger than [`MAX_RECORD_FILE_BYTES`] before reading
/// it whole (the read itself is bounded too, for a file whose size is not known up front).
fn read_bounded(path: &Path) -> Result<String, MotionError> {
    use std::io::Read as _;
    let io = |source| MotionError::Io {
        path: path.to_path_buf(),
        source,
    };
    let file = std::fs::File::open(path).map_err(io)?;
    let too_large = MotionError::FileTooLarge {
        limit_bytes: MAX_RECORD_FILE_BYTES,
    };
    if file.metadata().map_err(io)?.len() > MAX_RECORD_FILE_BYTES {
        return Err(too_large);
    }
    let mut text = String::new();
    file.take(MAX_RECORD_FILE_BYTES + 1)
        .read_to_string(&mut text)
        .map_err(io)?;
    if text.len() as u64 > MAX_RECORD_FILE_BYTES {
        return Err(too_large);
    }
    Ok(text)
}

fn check_samples(samples: usize, line: usize) -> Result<(), MotionError> {
    if samples > MAX_RECORD_SAMPLES {
        return Err(MotionError::TooManySamples {
            line,
            samples,
            limit: MAX_RECORD_SAMPLES,
        });
    }
    Ok(())
}

fn check_duration(duration_s: f64, line: usize) -> Result<(), MotionError> {
    if duration_s.is_nan() || duration_s > MAX_RECORD_DURATION_S {
        return Err(MotionError::TooLong {
            line,
            duration_s,
            limit_s: MAX_RECORD_DURATION_S,
        });
    }
    Ok(())
}

fn check_accel(value_g: f64, line: usize) -> Result<(), MotionError> {
    if value_g.abs() > MAX_RECORD_ACCEL_G {
        return Err(MotionError::AccelOutOfRange {
            line,
            value_g,
            limit_g: MAX_RECORD_ACCEL_G,
        });
    }
    Ok(())
}

/// Lines with their 1-based numbers, without the line terminator (LF or CRLF).
fn numbered_lines(text: &str) -> impl Iterator<Item = (usize, &str)> {
    text.split('\n')
        .enumerate()
        .map(|(i, l)| (i + 1, l.strip_suffix('\r').unwrap_or(l)))
}

fn looks_like_at2(text: &str) -> bool {
    numbered_lines(text)
        .take(4)
        .any(|(_, l)| l.to_ascii_uppercase().contains("NPTS"))
}

/// A number in a record: plain Rust float syntax plus Fortran's `D` exponent; NaN and infinity
/// are reported as non-finite, anything else as not numeric.
fn parse_value(token: &str, line: usize) -> Result<f64, MotionError> {
    let t = token.trim();
    let v = t
        .parse::<f64>()
        .or_else(|_| t.replace(['D', 'd'], "E").parse::<f64>())
        .map_err(|_| MotionError::NotNumeric {
            line,
            token: t.to_string(),
        })?;
    if v.is_finite() {
        Ok(v)
    } else {
        Err(MotionError::NonFinite { line })
    }
}

/// The text after `key` on an upper-cased header line, past blanks and one `=` or `:`, up to the next
/// blank or comma. `None` if the key is absent or nothing follows it.
fn header_value<'a>(upper: &'a str, key: &str) -> Option<&'a str> {
    let at = upper.find(key)?;
    let rest = upper.get(at + key.len()..)?.trim_start();
    let rest = rest
        .strip_prefix('=')
        .or_else(|| rest.strip_prefix(':'))
        .unwrap_or(rest)
        .trim_start();
    let end = rest
        .find(|c: char| c.is_whitespace() || c == ',')
        .unwrap_or(rest.len());
    let v = rest.get(..end)?;
    (!v.is_empty()).then_some(v)
}

/// The NPTS and DT texts of an upper-cased AT2 header line: `NPTS= 4000, DT= .01 SEC` (key-value,
/// comma optional), or the older PEER layout `4000 .0100 NPTS, DT` (values first).
fn at2_header_fields(upper: &str, line: usize) -> Result<(&str, &str), MotionError> {
    let mut leading = upper
        .split(|c: char| c.is_whitespace() || c == ',')
        .filter(|t| !t.is_empty());
    if let (Some(n), Some(dt), Some(key)) = (leading.next(), leading.next(), leading.next()) {
        let numeric = |t: &str| t.replace('D', "E").parse::<f64>().is_ok();
        if numeric(n) && numeric(dt) && key.starts_with("NPTS") && upper.contains("DT") {
            return Ok((n, dt));
        }
    }
    let npts = header_value(upper, "NPTS").ok_or(MotionError::MissingNpts { line })?;
    // Search for DT after NPTS so a name holding "DT" on the same line cannot be mistaken for it.
    let after_npts = upper.find("NPTS").map_or(0, |i| i + 4);
    let dt = upper
        .get(after_npts..)
        .and_then(|rest| header_value(rest, "DT"))
        .or_else(|| header_value(upper, "DT"))
        .ok_or(MotionError::MissingDt { line })?;
    Ok((npts, dt))
}

/// Parse a PEER AT2 record (see the module docs for the format).
pub fn parse_at2(text: &str, name: &str) -> Result<GroundMotion, MotionError> {
    if text.trim().is_empty() {
        return Err(MotionError::Empty);
    }
    let mut lines = numbered_lines(text);
    let mut header = None;
    for _ in 0..4 {
        header = lines.next();
    }
    let (hline, htext) = match header {
        Some(h) => h,
        None => {
            return Err(MotionError::ShortHeader {
                lines: numbered_lines(text.trim_end()).count(),
            })
        }
    };
    let upper = htext.to_ascii_uppercase();
    let (npts_text, dt_text) = at2_header_fields(&upper, hline)?;
    let npts: usize = npts_text.parse().map_err(|_| MotionError::NotNumeric {
        line: hline,
        token: npts_text.to_string(),
    })?;
    if npts == 0 {
        return Err(MotionError::ZeroNpts { line: hline });
    }
    let dt_s = parse_value(dt_text, hline).map_err(|e| match e {
        MotionError::NonFinite { line } => MotionError::BadDt {
            line,
            dt_s: f64::NAN,
        },
        other => other,
    })?;
    if dt_s <= 0.0 {
        return Err(MotionError::BadDt { line: hline, dt_s });
    }
    check_samples(npts, hline)?;
    check_duration((npts - 1) as f64 * dt_s, hline)?;
    // NPTS comes from the file: never reserve more than the text can hold (a value takes at least
    // two bytes), so a corrupt header cannot ask for gigabytes (found by `cargo fuzz`).
    let mut accel_g = Vec::with_capacity(npts.min(text.len() / 2 + 1));
    let mut found = 0_usize;
    for (line, l) in lines {
        for token in l
            .split(|c: char| c.is_whitespace() || c == ',')
            .filter(|t| !t.is_empty())
        {
            let a = parse_value(token, line)?;
            check_accel(a, line)?;
            // Values past NPTS are counted for the error, never stored.
            if found < npts {
                accel_g.push(a);
            }
            found += 1;
        }
    }
    if found != npts {
        return Err(MotionError::PointCount {
            expected: npts,
            found,
        });
    }
    Ok(GroundMotion {
        name: name.to_string(),
        dt_s,
        accel_g,
    })
}

/// Parse a two-column CSV record `time_s, accel_g` (see the module docs for the format).
pub fn parse_csv(text: &str, name: &str) -> Result<GroundMotion, MotionError> {
    if text.trim().is_empty() {
        return Err(MotionError::Empty);
    }
    let mut rows: Vec<(usize, f64, f64)> = Vec::new();
    let mut seen_content = false;
    for (line, l) in numbered_lines(text) {
        let l = l.trim();
        if l.is_empty() || l.starts_with('#') {
            continue;
        }
        let fields: Vec<&str> = l
            .split([',', ';', '\t'])
            .map(str::trim)
            .filter(|f| !f.is_empty())
            .collect();
        let first_content = !seen_content;
        seen_content = true;
        // The first non-comment line may be a header: all its fields non-numeric.
        if first_content && fields.iter().all(|f| f.parse::<f64>().is_err()) {
            continue;
        }
        let [t, a] = fields.as_slice() else {
            return Err(MotionError::ColumnCount {
                line,
                found: fields.len(),
            });
        };
        let a = parse_value(a, line)?;
        check_accel(a, line)?;
        rows.push((line, parse_value(t, line)?, a));
        check_samples(rows.len(), line)?;
    }
    match rows.len() {
        0 => return Err(MotionError::NoData),
        1 => return Err(MotionError::TooFewRows { rows: 1 }),
        _ => {}
    }
    let (first, last) = match (rows.first(), rows.last()) {
        (Some(f), Some(l)) => (*f, *l),
        _ => return Err(MotionError::NoData),
    };
    for w in rows.windows(2) {
        if let [(_, t0, _), (line, t1, _)] = w {
            if t1 <= t0 {
                return Err(MotionError::NonMonotonicTime {
                    line: *line,
                    time_s: *t1,
                    previous_s: *t0,
                });
            }
        }
    }
    check_duration(last.1 - first.1, last.0)?;
    // Judge each step against the median step, so a dropped sample is reported on its own line
    // rather than wherever the mean (which it shifts) first disagrees.
    let mut steps: Vec<f64> = rows
        .iter()
        .zip(rows.iter().skip(1))
        .map(|(a, b)| b.1 - a.1)
        .collect();
    steps.sort_by(f64::total_cmp);
    let median_step_s = steps.get(steps.len() / 2).copied().unwrap_or(0.0);
    for w in rows.windows(2) {
        if let [(_, t0, _), (line, t1, _)] = w {
            let step_s = t1 - t0;
            if (step_s - median_step_s).abs() > CSV_DT_TOLERANCE * median_step_s {
                return Err(MotionError::NonUniformTime {
                    line: *line,
                    step_s,
                    median_step_s,
                });
            }
        }
    }
    // Every step is within 1% of the median: the mean over the whole record is the best estimate.
    let mean_step_s = (last.1 - first.1) / (rows.len() - 1) as f64;
    if !(mean_step_s.is_finite() && mean_step_s > 0.0) {
        return Err(MotionError::BadDt {
            line: 0,
            dt_s: mean_step_s,
        });
    }
    Ok(GroundMotion {
        name: name.to_string(),
        dt_s: mean_step_s,
        accel_g: rows.into_iter().map(|(_, _, a)| a).collect(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;
    use rths_core::params::G_MM_S2;

    const H3: &str = "TITLE\nEVENT\nUNITS OF G\n";

    #[test]
    fn header_with_commas_lf() {
        let m = parse_at2(
            &format!("{H3}NPTS=  4, DT= .01000 SEC\n .1 -.2 .3\n .4\n"),
            "a",
        )
        .unwrap();
        assert_eq!(m.accel_g, vec![0.1, -0.2, 0.3, 0.4]);
        assert_eq!(m.dt_s, 0.01);
        assert_eq!(m.name, "a");
    }

    #[test]
    fn header_without_comma_crlf_varying_values_per_line() {
        let text = "T\r\nE\r\nU\r\nNPTS= 6  DT= .0050\r\n  .1E-01  -.2E+00\r\n 3.0\r\n\r\n 4 5 6.5e-3   \r\n";
        let m = parse_at2(text, "b").unwrap();
        assert_eq!(m.accel_g, vec![0.01, -0.2, 3.0, 4.0, 5.0, 6.5e-3]);
        assert_eq!(m.dt_s, 0.005);
    }

    #[test]
    fn header_variants() {
        for h in [
            "NPTS=   2000, DT=   .0200 SEC        ",
            "npts=2000 dt=0.02",
            "NPTS: 2000, DT: 0.02 SEC,",
            "NPTS = 2000 , DT = 2.0E-2",
            "   2000   .0200    NPTS, DT",
        ] {
            let body = "0.0 \n".repeat(2000);
            let m = parse_at2(&format!("{H3}{h}\n{body}"), "x").unwrap();
            assert_eq!(m.accel_g.len(), 2000, "{h}");
            assert!((m.dt_s - 0.02).abs() < 1e-15, "{h}");
        }
    }

    #[test]
    fn fortran_d_exponent() {
        let m = parse_at2(&format!("{H3}NPTS=2, DT=0.01\n0.1D-01 2.0d0\n"), "x").unwrap();
        assert_eq!(m.accel_g, vec![0.01, 2.0]);
    }

    #[test]
    fn at2_errors() {
        let e = |t: &str| parse_at2(t, "x").unwrap_err();
        assert!(matches!(e(""), MotionError::Empty));
        assert!(matches!(e(" \r\n\n  "), MotionError::Empty));
        assert!(matches!(e("A\nB\n"), MotionError::ShortHeader { lines: 2 }));
        assert!(matches!(
            e(&format!("{H3}DT= 0.01\n1\n")),
            MotionError::MissingNpts { line: 4 }
        ));
        assert!(matches!(
            e(&format!("{H3}NPTS= 1\n1\n")),
            MotionError::MissingDt { line: 4 }
        ));
        assert!(matches!(
            e(&format!("{H3}NPTS= 1, DT= SEC\n1\n")),
            MotionError::NotNumeric { line: 4, ref token } if token == "SEC"
        ));
        assert!(matches!(
            e(&format!("{H3}NPTS= 0, DT= 0.01\n")),
            MotionError::ZeroNpts { line: 4 }
        ));
        assert!(matches!(
            e(&format!("{H3}NPTS= 1, DT= -0.01\n1\n")),
            MotionError::BadDt { line: 4, .. }
        ));
        assert!(matches!(
            e(&format!("{H3}NPTS= 1, DT= 0\n1\n")),
            MotionError::BadDt { line: 4, .. }
        ));
        assert!(matches!(
            e(&format!("{H3}NPTS= 3, DT= 0.01\n1 2\n")),
            MotionError::PointCount {
                expected: 3,
                found: 2
            }
        ));
        assert!(matches!(
            e(&format!("{H3}NPTS= 1, DT= 0.01\n1 2\n")),
            MotionError::PointCount {
                expected: 1,
                found: 2
            }
        ));
        assert!(matches!(
            e(&format!("{H3}NPTS= 3, DT= 0.01\r\n1 2\r\n3 4x\r\n")),
            MotionError::NotNumeric { line: 6, ref token } if token == "4x"
        ));
        assert!(matches!(
            e(&format!("{H3}NPTS= 3, DT= 0.01\n1\n2\nNaN\n")),
            MotionError::NonFinite { line: 7 }
        ));
        assert!(matches!(
            e(&format!("{H3}NPTS= 2, DT= 0.01\n1 inf\n")),
            MotionError::NonFinite { line: 5 }
        ));
    }

    #[test]
    fn csv_reads_with_and_without_header() {
        let m = parse_csv("time_s,accel_g\n0,0.1\n0.01,-0.2\n0.02,0.3\n", "c").unwrap();
        assert_eq!(m.accel_g, vec![0.1, -0.2, 0.3]);
        assert!((m.dt_s - 0.01).abs() < 1e-15);
        let m = parse_csv("# comment\r\n0.0; 1\r\n0.5;2\r\n\r\n1.0 ;3\r\n", "c").unwrap();
        assert_eq!(m.accel_g, vec![1.0, 2.0, 3.0]);
        assert_eq!(m.dt_s, 0.5);
    }

    #[test]
    fn csv_errors() {
        let e = |t: &str| parse_csv(t, "x").unwrap_err();
        assert!(matches!(e(""), MotionError::Empty));
        assert!(matches!(e("time_s,accel_g\n"), MotionError::NoData));
        assert!(matches!(e("0,1\n"), MotionError::TooFewRows { rows: 1 }));
        assert!(matches!(
            e("t,a\n0,1\n0.01,1,3\n"),
            MotionError::ColumnCount { line: 3, found: 3 }
        ));
        assert!(matches!(
            e("t,a\n0,1\n0.01,abc\n"),
            MotionError::NotNumeric { line: 3, ref token } if token == "abc"
        ));
        // A second header-like line is an error, not a header.
        assert!(matches!(
            e("t,a\nt,a\n0,1\n"),
            MotionError::NotNumeric { line: 2, .. }
        ));
        assert!(matches!(
            e("0,1\n0.01,nan\n"),
            MotionError::NonFinite { line: 2 }
        ));
        assert!(matches!(
            e("0,1\n0.01,1\n0.01,1\n0.03,1\n"),
            MotionError::NonMonotonicTime { line: 3, .. }
        ));
        assert!(matches!(
            e("0,1\n0.01,1\n0.03,1\n0.04,1\n0.05,1\n"),
            MotionError::NonUniformTime { line: 3, .. }
        ));
        // Within the 1% tolerance: times rounded to 6 decimals at dt = 1/2048 s.
        let rounded: String = (0..100)
            .map(|k| format!("{:.6},0\n", k as f64 / 2048.0))
            .collect();
        assert!(parse_csv(&rounded, "r").is_ok());
    }

    #[test]
    fn line_numbers_count_crlf_lines() {
        let err = parse_csv("t,a\r\n0,1\r\n\r\n0.01,x\r\n", "x").unwrap_err();
        assert!(matches!(err, MotionError::NotNumeric { line: 4, .. }));
        assert!(err.to_string().starts_with("line 4:"), "{err}");
    }

    #[test]
    fn resample_is_exact_on_a_ramp() {
        // a(t) = 2t + 0.5 g sampled at 0.01 s: linear interpolation reproduces it exactly.
        let m = GroundMotion {
            name: "ramp".into(),
            dt_s: 0.01,
            accel_g: (0..=100).map(|k| 2.0 * k as f64 * 0.01 + 0.5).collect(),
        };
        let dt = 1.0 / 2048.0;
        let r = m.resample_mm_s2(dt);
        assert_eq!(r.len(), 2048 + 1); // duration 1 s exactly
        for (k, a) in r.iter().enumerate() {
            let t = k as f64 * dt;
            assert!((a - (2.0 * t + 0.5) * G_MM_S2).abs() < 1e-9, "k={k}");
        }
        // Non-divisible duration: floor(0.995 / 0.01) = 99 steps -> 100 samples.
        let short = GroundMotion {
            accel_g: m.accel_g[..100].to_vec(),
            ..m.clone()
        };
        assert_eq!(short.resample_mm_s2(0.01).len(), 100);
        assert_eq!(short.resample_mm_s2(0.011).len(), 91); // floor(0.99/0.011)=90
        assert!(m.resample_mm_s2(0.0).is_empty());
        assert!(m.resample_mm_s2(f64::NAN).is_empty());
        // Same step: the samples themselves.
        let same = m.resample_mm_s2(0.01);
        for (a, g) in same.iter().zip(&m.accel_g) {
            assert!((a - g * G_MM_S2).abs() < 1e-9);
        }
    }

    #[test]
    fn limits_refused_before_storing() {
        // A DT typo (100 s or 10 s for 0.01 s) makes a record of days: refused from the header.
        for dt in ["100", "10"] {
            let text = format!("{H3}NPTS= 4000, DT= {dt} SEC\n{}", "0.1\n".repeat(4000));
            assert!(matches!(
                parse_at2(&text, "x").unwrap_err(),
                MotionError::TooLong { line: 4, .. }
            ));
        }
        // NPTS past the sample limit: refused from the header, whatever follows.
        assert!(matches!(
            parse_at2(&format!("{H3}NPTS= 99999999, DT= 0.000001\n1\n"), "x").unwrap_err(),
            MotionError::TooManySamples { line: 4, .. }
        ));
        // A CSV time column in the wrong units: 3 rows spanning 2e6 s.
        let e = parse_csv("time_s,accel_g\n0,0.1\n1e6,0.2\n2e6,0.1\n", "x").unwrap_err();
        assert!(matches!(e, MotionError::TooLong { line: 4, .. }), "{e}");
        assert!(e.to_string().contains("2.000000e6 s"), "{e}");
        // Values beyond ±20 g, named by line and printed compactly.
        let e = parse_csv("0,0.1\n0.01,1e308\n", "x").unwrap_err();
        assert!(
            matches!(e, MotionError::AccelOutOfRange { line: 2, .. }),
            "{e}"
        );
        assert!(e.to_string().contains("1.000000e308 g"), "{e}");
        assert!(matches!(
            parse_at2(&format!("{H3}NPTS= 2, DT= 0.01\n0.1 -981\n"), "x").unwrap_err(),
            MotionError::AccelOutOfRange { line: 5, .. }
        ));
        // At the limits: accepted.
        let n = (MAX_RECORD_DURATION_S / 0.5) as usize + 1;
        let m = parse_at2(
            &format!("{H3}NPTS= {n}, DT= 0.5\n{}", "20\n".repeat(n)),
            "x",
        )
        .unwrap();
        assert_eq!(m.duration_s(), MAX_RECORD_DURATION_S);
        m.validate().unwrap();
        // `validate` holds records built or scaled in code to the same limits.
        assert!(matches!(
            m.scaled(1.5).validate().unwrap_err(),
            MotionError::AccelOutOfRange { .. }
        ));
        let long = GroundMotion {
            name: "l".into(),
            dt_s: 1.0,
            accel_g: vec![0.0; 700],
        };
        assert!(matches!(
            long.validate().unwrap_err(),
            MotionError::TooLong { .. }
        ));
    }

    #[test]
    fn file_that_never_ends_is_refused() {
        // /dev/zero has no size up front: the bounded read stops at the limit.
        let p = Path::new("/dev/zero");
        if p.exists() {
            assert!(matches!(
                GroundMotion::from_path(p).unwrap_err(),
                MotionError::FileTooLarge { .. }
            ));
        }
    }

    #[test]
    fn scale_duration_pga() {
        let m = GroundMotion {
            name: "m".into(),
            dt_s: 0.02,
            accel_g: vec![0.1, -0.3, 0.2],
        };
        assert_eq!(m.pga_g(), 0.3);
        assert!((m.duration_s() - 0.04).abs() < 1e-15);
        let s = m.scaled(2.0);
        assert_eq!(s.accel_g, vec![0.2, -0.6, 0.4]);
        assert!((s.pga_g() - 0.6).abs() < 1e-15);
        assert_eq!(m.scaled(1.0).name, "m");
    }

    #[test]
    fn embedded_records_parse() {
        assert_eq!(GroundMotion::embedded_names().len(), 4);
        for name in GroundMotion::embedded_names() {
            let m = GroundMotion::try_embedded(name).unwrap();
            m.validate().unwrap();
        }
        let e = GroundMotion::try_el_centro().unwrap();
        assert_eq!(GroundMotion::el_centro(), e);
        assert_eq!(e.accel_g.len(), 4000);
        assert_eq!(GroundMotion::embedded("IELC180.at2"), Some(e.clone()));
        assert_eq!(GroundMotion::embedded("El-Centro"), Some(e));
        assert!(GroundMotion::embedded("nope").is_none());
        assert!(matches!(
            GroundMotion::try_embedded("nope"),
            Err(MotionError::UnknownRecord { .. })
        ));
    }

    #[test]
    fn from_path_by_extension_and_sniffing() {
        let dir = tempfile::tempdir().unwrap();
        let m = GroundMotion {
            name: "rec".into(),
            dt_s: 0.01,
            accel_g: vec![0.1, 0.2, -0.3],
        };
        for (file, text) in [
            ("rec.AT2", m.to_at2()),
            ("rec.csv", m.to_csv()),
            ("rec.txt", m.to_at2()),
            ("rec.dat", m.to_csv()),
        ] {
            let p = dir.path().join(file);
            std::fs::write(&p, text).unwrap();
            let r = GroundMotion::from_path(&p).unwrap();
            assert_eq!(r.accel_g, m.accel_g, "{file}");
            assert_eq!(r.name, "rec");
        }
        let missing = dir.path().join("missing.at2");
        assert!(matches!(
            GroundMotion::from_path(&missing),
            Err(MotionError::Io { .. })
        ));
    }

    fn record() -> impl Strategy<Value = GroundMotion> {
        (
            prop::collection::vec(-5.0f64..5.0, 2..300),
            1e-4f64..0.1,
            prop::sample::select(vec![1e-300, 1e-6, 1.0, 4.0]),
        )
            .prop_map(|(a, dt_s, mag)| GroundMotion {
                name: "p".into(),
                dt_s,
                accel_g: a.into_iter().map(|v| v * mag).collect(),
            })
    }

    proptest! {
        #[test]
        fn at2_round_trips(m in record()) {
            let r = parse_at2(&m.to_at2(), "p").unwrap();
            prop_assert_eq!(r, m);
        }

        #[test]
        fn at2_round_trips_crlf(m in record()) {
            let r = parse_at2(&m.to_at2().replace('\n', "\r\n"), "p").unwrap();
            prop_assert_eq!(r, m);
        }

        #[test]
        fn csv_round_trips(m in record()) {
            let r = parse_csv(&m.to_csv(), "p").unwrap();
            prop_assert_eq!(&r.accel_g, &m.accel_g);
            prop_assert!((r.dt_s - m.dt_s).abs() <= 1e-9 * m.dt_s);
        }
    }
}
