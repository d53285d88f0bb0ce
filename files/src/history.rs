//! Time histories a lab's FE program writes of its numerical model with a numerical stand-in
//! for the specimen: the training data of `rths train nonlinear --histories` (docs/opensees-nonlinear.md,
//! "Time histories as training data").
//!
//! Two layouts, one result ([`TimeHistory`]):
//! - **CSV**, one file per run: the header `time_s,ground_accel_mm_s2,specimen_force_kn,interface_mm`
//!   then one `out_<NODE>_<DOF>_mm` column per output, one row per controller step.
//! - **OpenSees recorder files**, one directory per run: `ground_accel.out`, `specimen_force.out`,
//!   `interface_disp.out` and one `out_<NODE>_<DOF>.out` per output, each two whitespace columns
//!   (`time value`, what `recorder Node -file F -time -node N -dof D disp` writes), in the model's
//!   units (converted by the caller's [`RecorderUnits`]).
//!
//! Every error names the file and, where there is one, its 1-based line. The rate is the one rule
//! of [`crate::rate`]: a history sampled at another step than the controller's is refused.

use std::path::{Path, PathBuf};

use crate::motion::MAX_RECORD_FILE_BYTES;
use crate::rate::{check_dt, OtherRate};

/// The CSV's fixed columns, in order.
pub const CSV_COLUMNS: [&str; 4] = [
    "time_s",
    "ground_accel_mm_s2",
    "specimen_force_kn",
    "interface_mm",
];

/// The recorder files every run's directory holds (besides one `out_<NODE>_<DOF>.out` per output).
pub const RECORDER_FILES: [&str; 3] = [
    "ground_accel.out",
    "specimen_force.out",
    "interface_disp.out",
];

/// Most rows a history may hold (about 34 min at 2048 Hz), so a typo cannot ask for gigabytes.
pub const MAX_HISTORY_ROWS: usize = 1 << 22;

/// Most outputs a history may carry.
pub const MAX_HISTORY_OUTPUTS: usize = 64;

/// A step may differ from the file's mean step by this fraction at most: a gap (a missing row) is
/// a step of 2·dt, and a time column printed with 6 decimals at 2048 Hz is off by 2e-3 of a step.
pub const STEP_TOLERANCE: f64 = 0.01;

/// One output DOF of a history (an OpenSees node and DOF, 1-based; a story structure's floor and 1).
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct OutputDof {
    /// Node tag (a story structure: the floor, 1 = first floor).
    pub node: u32,
    /// DOF at the node, 1-based.
    pub dof: u32,
}

impl OutputDof {
    /// The CSV column name, `out_<NODE>_<DOF>_mm`.
    pub fn column(self) -> String {
        format!("out_{}_{}_mm", self.node, self.dof)
    }

    /// The recorder file name, `out_<NODE>_<DOF>.out`.
    pub fn recorder_file(self) -> String {
        format!("out_{}_{}.out", self.node, self.dof)
    }

    /// Parse `out_<NODE>_<DOF><suffix>`.
    fn parse(name: &str, suffix: &str) -> Option<Self> {
        let mid = name.strip_prefix("out_")?.strip_suffix(suffix)?;
        let (n, d) = mid.split_once('_')?;
        let node = n.parse().ok()?;
        let dof: u32 = d.parse().ok()?;
        (dof >= 1).then_some(Self { node, dof })
    }
}

/// One run's time histories, in rths units (mm, kN, s), uniformly sampled at `dt_s`.
#[derive(Debug, Clone, PartialEq)]
pub struct TimeHistory {
    /// Where it was read from (the CSV file or the recorder directory).
    pub source: PathBuf,
    /// The step, s (the controller's, checked).
    pub dt_s: f64,
    /// Ground acceleration, mm/s².
    pub ground_accel_mm_s2: Vec<f64>,
    /// The stand-in specimen's force at the interface (positive with the interface displacement),
    /// kN.
    pub specimen_force_kn: Vec<f64>,
    /// Interface (specimen DOF) displacement, mm.
    pub interface_mm: Vec<f64>,
    /// Each output's displacement, mm, in the file's order.
    pub outputs: Vec<(OutputDof, Vec<f64>)>,
    /// Each row's 1-based line in the file it was read from (of a recorder directory, in the
    /// interface's file); empty for a history made in memory. For errors found after reading.
    pub row_line: Vec<usize>,
}

impl TimeHistory {
    /// Rows (steps).
    pub fn len(&self) -> usize {
        self.ground_accel_mm_s2.len()
    }

    /// Whether it has no rows (never, for a history that was read).
    pub fn is_empty(&self) -> bool {
        self.ground_accel_mm_s2.is_empty()
    }

    /// The output at `dof`, if the history has it.
    pub fn output(&self, dof: OutputDof) -> Option<&[f64]> {
        self.outputs
            .iter()
            .find(|(d, _)| *d == dof)
            .map(|(_, v)| v.as_slice())
    }

    /// Where row `k` (0-based) was read: `FILE: line L` (the CSV, or the interface's recorder
    /// file), or `FILE: data row k+1` for a history made in memory.
    pub fn row_at(&self, k: usize) -> String {
        match self.row_line.get(k) {
            Some(line) if self.source.is_dir() => format!(
                "{}: line {line}",
                self.source.join(RECORDER_FILES[2]).display()
            ),
            Some(line) => format!("{}: line {line}", self.source.display()),
            None => format!("{}: data row {}", self.source.display(), k + 1),
        }
    }
}

/// Why a history could not be read. `file` is the file; `line` 1-based.
#[derive(Debug, thiserror::Error)]
pub enum HistoryError {
    /// The file or directory could not be read.
    #[error("{file}: cannot read: {source}")]
    Io {
        /// The file.
        file: PathBuf,
        /// The underlying error.
        source: std::io::Error,
    },
    /// Larger than [`MAX_RECORD_FILE_BYTES`].
    #[error("{file}: larger than the {limit_bytes}-byte limit of a history file")]
    TooLarge {
        /// The file.
        file: PathBuf,
        /// The limit, bytes.
        limit_bytes: u64,
    },
    /// More rows than [`MAX_HISTORY_ROWS`] or outputs than [`MAX_HISTORY_OUTPUTS`].
    #[error("{file}: {what} (more than the limit of {limit})")]
    TooMany {
        /// The file.
        file: PathBuf,
        /// What there is too much of.
        what: String,
        /// The limit.
        limit: usize,
    },
    /// Nothing in the file but blank lines.
    #[error(
        "{file}: empty (a history file holds a header, time_s,ground_accel_mm_s2,\
         specimen_force_kn,interface_mm, then out_<NODE>_<DOF>_mm per output, and a row a step)"
    )]
    Empty {
        /// The file.
        file: PathBuf,
    },
    /// No header, or a header without one of [`CSV_COLUMNS`] in its place.
    #[error(
        "{file}: line 1: column {position} must be `{expected}`, found `{found}` (the header is \
         time_s,ground_accel_mm_s2,specimen_force_kn,interface_mm, then out_<NODE>_<DOF>_mm per output)"
    )]
    MissingColumn {
        /// The file.
        file: PathBuf,
        /// 1-based column.
        position: usize,
        /// The column expected there.
        expected: String,
        /// What the header has there (empty if nothing).
        found: String,
    },
    /// A column after the fixed four that is not `out_<NODE>_<DOF>_mm`, or one given twice.
    #[error("{file}: line 1: column {position} `{found}` is {why}")]
    BadColumn {
        /// The file.
        file: PathBuf,
        /// 1-based column.
        position: usize,
        /// The column's name.
        found: String,
        /// What is wrong with it.
        why: String,
    },
    /// A recorder directory without one of its files.
    #[error("{file}: missing (a recorder directory holds {})", RECORDER_FILES.join(", "))]
    MissingFile {
        /// The missing file.
        file: PathBuf,
    },
    /// A row with another number of fields than the header (CSV) or than `time value` (recorder).
    #[error("{file}: line {line}: {found} columns, expected {expected}")]
    ColumnCount {
        /// The file.
        file: PathBuf,
        /// 1-based line.
        line: usize,
        /// Fields expected.
        expected: usize,
        /// Fields found.
        found: usize,
    },
    /// A field that is not a number.
    #[error("{file}: line {line}: column `{column}`: `{token}` is not a number")]
    NotNumeric {
        /// The file.
        file: PathBuf,
        /// 1-based line.
        line: usize,
        /// The column.
        column: String,
        /// The text.
        token: String,
    },
    /// NaN or infinity.
    #[error("{file}: line {line}: column `{column}` is not finite (NaN or infinity)")]
    NonFinite {
        /// The file.
        file: PathBuf,
        /// 1-based line.
        line: usize,
        /// The column.
        column: String,
    },
    /// Fewer than two rows: no step.
    #[error("{file}: {rows} data rows; a history needs at least 2 to define its step")]
    TooFewRows {
        /// The file.
        file: PathBuf,
        /// Rows found.
        rows: usize,
    },
    /// A step that is not the file's mean step (a gap, a repeated or uneven time).
    #[error(
        "{file}: line {line}: time step {step_s:e} s is not the file's step {dt_s:e} s (a gap or \
         uneven time: a history is sampled uniformly at the controller's rate)"
    )]
    UnevenTime {
        /// The file.
        file: PathBuf,
        /// 1-based line the step ends on.
        line: usize,
        /// The step there, s.
        step_s: f64,
        /// The file's mean step, s.
        dt_s: f64,
    },
    /// Sampled at another rate than the controller's.
    #[error("{file}: {source}")]
    OtherRate {
        /// The file.
        file: PathBuf,
        /// The rate rule's error.
        source: OtherRate,
    },
    /// Recorder files of one run that disagree in length or time.
    #[error(
        "{file}: line {line}: {why} (every file of a run has the same rows, at the same times)"
    )]
    Mismatch {
        /// The file.
        file: PathBuf,
        /// 1-based line.
        line: usize,
        /// What differs.
        why: String,
    },
}

/// The factors from a recorder directory's model units to rths's (mm, kN).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RecorderUnits {
    /// Model length to mm (1000 for metres, 1 for mm).
    pub length_to_mm: f64,
    /// Model force to kN (1e-3 for N, 1 for kN).
    pub force_to_kn: f64,
}

impl RecorderUnits {
    /// mm and kN: the factors are 1.
    pub const MM_KN: Self = Self {
        length_to_mm: 1.0,
        force_to_kn: 1.0,
    };
    /// SI (m, N).
    pub const SI: Self = Self {
        length_to_mm: 1000.0,
        force_to_kn: 1e-3,
    };
}

fn read_bounded(file: &Path) -> Result<String, HistoryError> {
    use std::io::Read as _;
    let io = |source| HistoryError::Io {
        file: file.to_path_buf(),
        source,
    };
    let f = std::fs::File::open(file).map_err(io)?;
    let mut text = String::new();
    f.take(MAX_RECORD_FILE_BYTES + 1)
        .read_to_string(&mut text)
        .map_err(io)?;
    if text.len() as u64 > MAX_RECORD_FILE_BYTES {
        return Err(HistoryError::TooLarge {
            file: file.to_path_buf(),
            limit_bytes: MAX_RECORD_FILE_BYTES,
        });
    }
    Ok(text)
}

/// Non-blank lines with their 1-based numbers, without `\r`.
fn lines(text: &str) -> impl Iterator<Item = (usize, &str)> {
    text.split('\n')
        .enumerate()
        .map(|(i, l)| (i + 1, l.strip_suffix('\r').unwrap_or(l).trim()))
        .filter(|(_, l)| !l.is_empty())
}

fn number(file: &Path, line: usize, column: &str, token: &str) -> Result<f64, HistoryError> {
    let v: f64 = token.trim().parse().map_err(|_| HistoryError::NotNumeric {
        file: file.to_path_buf(),
        line,
        column: column.to_string(),
        token: token.trim().to_string(),
    })?;
    if !v.is_finite() {
        return Err(HistoryError::NonFinite {
            file: file.to_path_buf(),
            line,
            column: column.to_string(),
        });
    }
    Ok(v)
}

/// How far the number `token` stands for may be from it, as printed: half a unit of its last digit,
/// at most half a unit of the 6th significant digit (`5e-6 × |value|`). OpenSees's recorders print
/// 6 significant digits unless told `-precision`, so a time of 48.8281 s is known to 5e-5 s, a
/// tenth of a 4096 Hz step; a shorter print ("0", "0.5", a writer's shortest round trip) is taken
/// as that precise at least.
pub fn printed_resolution(token: &str) -> f64 {
    let t = token.trim();
    let (mantissa, exponent) = match t.find(['e', 'E']) {
        Some(i) => (&t[..i], t[i + 1..].parse::<i32>().unwrap_or(0)),
        None => (t, 0),
    };
    let decimals = mantissa.find('.').map_or(0, |i| {
        mantissa[i + 1..]
            .chars()
            .filter(char::is_ascii_digit)
            .count()
    });
    let decimals = i32::try_from(decimals).unwrap_or(i32::MAX);
    let last_digit = 0.5 * 10f64.powi(exponent.saturating_sub(decimals));
    let value = t.parse::<f64>().map_or(0.0, f64::abs);
    last_digit.min(SIX_DIGITS_REL * value)
}

/// Half a unit of the 6th significant digit, relative to the value: at most 5e-6.
const SIX_DIGITS_REL: f64 = 5e-6;

/// The uniform step of `times` (1-based `lines` of each, each known to `res` as printed), checked
/// against `run_dt_s`.
fn uniform_step(
    file: &Path,
    times: &[f64],
    res: &[f64],
    lines: &[usize],
    run_dt_s: f64,
) -> Result<f64, HistoryError> {
    let n = times.len();
    if n < 2 {
        return Err(HistoryError::TooFewRows {
            file: file.to_path_buf(),
            rows: n,
        });
    }
    // Each step against the median step (a gap shows on its own line), then the rate from the
    // mean over the whole file: a time column printed with few digits still gives the step to a
    // part in 1e6 over a run of any useful length. A step is allowed the rounding of the two
    // times it is the difference of, and of the two the median is.
    let mut steps: Vec<f64> = times.windows(2).map(|w| w[1] - w[0]).collect();
    steps.sort_by(f64::total_cmp);
    let median = steps[steps.len() / 2];
    let mut sorted_res = res.to_vec();
    sorted_res.sort_by(f64::total_cmp);
    let median_res = sorted_res.get(sorted_res.len() / 2).copied().unwrap_or(0.0);
    let r = |k: usize| res.get(k).copied().unwrap_or(0.0);
    for k in 1..n {
        let step = times[k] - times[k - 1];
        let allowed = STEP_TOLERANCE * median + r(k) + r(k - 1) + 2.0 * median_res;
        if median <= 0.0 || (step - median).abs() > allowed {
            return Err(HistoryError::UnevenTime {
                file: file.to_path_buf(),
                line: lines[k],
                step_s: step,
                dt_s: median,
            });
        }
    }
    let dt = (times[n - 1] - times[0]) / (n - 1) as f64;
    check_dt(
        "time history",
        dt,
        run_dt_s,
        // The shipped writer of OpenSees runs; another FE program's run at that step serves too.
        &format!("scripts/opensees/write_histories.py MODEL.py ... --dt {run_dt_s}"),
    )
    .map_err(|source| HistoryError::OtherRate {
        file: file.to_path_buf(),
        source,
    })?;
    Ok(run_dt_s)
}

/// Parse a history CSV (`text` of `file`), sampled at the controller's step `run_dt_s`.
pub fn parse_csv(text: &str, file: &Path, run_dt_s: f64) -> Result<TimeHistory, HistoryError> {
    let mut it = lines(text);
    let Some((_, first)) = it.next() else {
        return Err(HistoryError::Empty {
            file: file.to_path_buf(),
        });
    };
    let header: Vec<&str> = first.split(',').map(str::trim).collect();
    for (i, want) in CSV_COLUMNS.iter().enumerate() {
        let found = header.get(i).copied().unwrap_or("");
        if found != *want {
            return Err(HistoryError::MissingColumn {
                file: file.to_path_buf(),
                position: i + 1,
                expected: want.to_string(),
                found: found.to_string(),
            });
        }
    }
    let mut outputs: Vec<OutputDof> = Vec::new();
    for (i, name) in header.iter().enumerate().skip(CSV_COLUMNS.len()) {
        let bad = |why: &str| HistoryError::BadColumn {
            file: file.to_path_buf(),
            position: i + 1,
            found: name.to_string(),
            why: why.to_string(),
        };
        let d = OutputDof::parse(name, "_mm").ok_or_else(|| bad("not out_<NODE>_<DOF>_mm"))?;
        if outputs.contains(&d) {
            return Err(bad("given twice"));
        }
        outputs.push(d);
    }
    if outputs.len() > MAX_HISTORY_OUTPUTS {
        return Err(HistoryError::TooMany {
            file: file.to_path_buf(),
            what: format!("{} outputs", outputs.len()),
            limit: MAX_HISTORY_OUTPUTS,
        });
    }
    let width = header.len();
    let mut cols: Vec<Vec<f64>> = vec![Vec::new(); width];
    let mut time_res = Vec::new();
    let mut line_of = Vec::new();
    for (line, row) in it {
        if line_of.len() >= MAX_HISTORY_ROWS {
            return Err(HistoryError::TooMany {
                file: file.to_path_buf(),
                what: format!("more than {MAX_HISTORY_ROWS} rows"),
                limit: MAX_HISTORY_ROWS,
            });
        }
        let fields: Vec<&str> = row.split(',').collect();
        if fields.len() != width {
            return Err(HistoryError::ColumnCount {
                file: file.to_path_buf(),
                line,
                expected: width,
                found: fields.len(),
            });
        }
        for ((c, f), name) in cols.iter_mut().zip(&fields).zip(&header) {
            c.push(number(file, line, name, f)?);
        }
        time_res.push(fields.first().map_or(0.0, |f| printed_resolution(f)));
        line_of.push(line);
    }
    let dt_s = uniform_step(file, &cols[0], &time_res, &line_of, run_dt_s)?;
    let mut cols = cols.into_iter().skip(1);
    let mut next = || cols.next().unwrap_or_default();
    let ground_accel_mm_s2 = next();
    let specimen_force_kn = next();
    let interface_mm = next();
    let outputs = outputs.into_iter().map(|d| (d, next())).collect();
    Ok(TimeHistory {
        source: file.to_path_buf(),
        dt_s,
        ground_accel_mm_s2,
        specimen_force_kn,
        interface_mm,
        outputs,
        row_line: line_of,
    })
}

/// Read a history CSV file.
pub fn read_csv(file: &Path, run_dt_s: f64) -> Result<TimeHistory, HistoryError> {
    parse_csv(&read_bounded(file)?, file, run_dt_s)
}

/// One recorder file's rows.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct RecorderRows {
    /// The first column, s.
    pub time_s: Vec<f64>,
    /// The second column, in the model's units.
    pub value: Vec<f64>,
    /// Each row's 1-based line.
    pub line: Vec<usize>,
    /// How far each time may be from the one printed ([`printed_resolution`]), s.
    pub time_res_s: Vec<f64>,
}

/// One recorder file's `time value` rows.
pub fn parse_recorder(text: &str, file: &Path) -> Result<RecorderRows, HistoryError> {
    let (mut t, mut v, mut l, mut res) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
    for (line, row) in lines(text) {
        if l.len() >= MAX_HISTORY_ROWS {
            return Err(HistoryError::TooMany {
                file: file.to_path_buf(),
                what: format!("more than {MAX_HISTORY_ROWS} rows"),
                limit: MAX_HISTORY_ROWS,
            });
        }
        let fields: Vec<&str> = row.split_whitespace().collect();
        if fields.len() != 2 {
            return Err(HistoryError::ColumnCount {
                file: file.to_path_buf(),
                line,
                expected: 2,
                found: fields.len(),
            });
        }
        t.push(number(file, line, "time", fields[0])?);
        v.push(number(file, line, "value", fields[1])?);
        res.push(printed_resolution(fields[0]));
        l.push(line);
    }
    Ok(RecorderRows {
        time_s: t,
        value: v,
        line: l,
        time_res_s: res,
    })
}

/// Read a run's recorder directory `dir` (the files of [`RECORDER_FILES`] and every
/// `out_<NODE>_<DOF>.out` in it, outputs sorted by node and DOF), in `units`.
pub fn read_recorder_dir(
    dir: &Path,
    units: RecorderUnits,
    run_dt_s: f64,
) -> Result<TimeHistory, HistoryError> {
    let io = |source| HistoryError::Io {
        file: dir.to_path_buf(),
        source,
    };
    let mut outputs: Vec<OutputDof> = Vec::new();
    for entry in std::fs::read_dir(dir).map_err(io)? {
        let name = entry.map_err(io)?.file_name();
        if let Some(d) = name.to_str().and_then(|n| OutputDof::parse(n, ".out")) {
            outputs.push(d);
        }
    }
    outputs.sort();
    if outputs.len() > MAX_HISTORY_OUTPUTS {
        return Err(HistoryError::TooMany {
            file: dir.to_path_buf(),
            what: format!("{} outputs", outputs.len()),
            limit: MAX_HISTORY_OUTPUTS,
        });
    }
    let read = |name: &str| -> Result<_, HistoryError> {
        let file = dir.join(name);
        if !file.is_file() {
            return Err(HistoryError::MissingFile { file });
        }
        let text = read_bounded(&file)?;
        let r = parse_recorder(&text, &file)?;
        Ok((file, r))
    };
    let (first, ground) = read(RECORDER_FILES[0])?;
    let (times, ag, line_of, times_res) =
        (ground.time_s, ground.value, ground.line, ground.time_res_s);
    let dt_s = uniform_step(&first, &times, &times_res, &line_of, run_dt_s)?;
    // Row by row first, so a missing or repeated row shows on its own line, then the count.
    let same = |name: &str| -> Result<(Vec<f64>, Vec<usize>), HistoryError> {
        let (file, rows) = read(name)?;
        let (t, v, l, t_res) = (rows.time_s, rows.value, rows.line, rows.time_res_s);
        for (k, (a, b)) in t.iter().zip(&times).enumerate() {
            let allowed = STEP_TOLERANCE * dt_s
                + t_res.get(k).copied().unwrap_or(0.0)
                + times_res.get(k).copied().unwrap_or(0.0);
            if (a - b).abs() > allowed {
                return Err(HistoryError::Mismatch {
                    file,
                    line: l[k],
                    why: format!("time {a} s where {} has {b} s", RECORDER_FILES[0]),
                });
            }
        }
        if t.len() < times.len() {
            return Err(HistoryError::Mismatch {
                line: l.last().map_or(1, |last| last + 1),
                why: format!(
                    "the file ends after {} rows where {} has {}",
                    t.len(),
                    RECORDER_FILES[0],
                    times.len()
                ),
                file,
            });
        }
        if t.len() > times.len() {
            return Err(HistoryError::Mismatch {
                line: l[times.len()],
                why: format!(
                    "a row past the {} rows of {}",
                    times.len(),
                    RECORDER_FILES[0]
                ),
                file,
            });
        }
        Ok((v, l))
    };
    let scale = |v: Vec<f64>, f: f64| v.into_iter().map(|x| x * f).collect::<Vec<_>>();
    let specimen_force_kn = scale(same(RECORDER_FILES[1])?.0, units.force_to_kn);
    let (interface, row_line) = same(RECORDER_FILES[2])?;
    let interface_mm = scale(interface, units.length_to_mm);
    let outputs = outputs
        .into_iter()
        .map(|d| Ok((d, scale(same(&d.recorder_file())?.0, units.length_to_mm))))
        .collect::<Result<Vec<_>, HistoryError>>()?;
    Ok(TimeHistory {
        source: dir.to_path_buf(),
        dt_s,
        ground_accel_mm_s2: scale(ag, units.length_to_mm),
        specimen_force_kn,
        interface_mm,
        outputs,
        row_line,
    })
}

/// Read one history: a recorder directory if `path` is a directory, else a CSV file.
pub fn read(path: &Path, units: RecorderUnits, run_dt_s: f64) -> Result<TimeHistory, HistoryError> {
    if path.is_dir() {
        read_recorder_dir(path, units, run_dt_s)
    } else {
        read_csv(path, run_dt_s)
    }
}

/// The CSV text of `h` (the layout [`parse_csv`] reads; 17 significant digits, times `k·dt_s`).
pub fn to_csv(h: &TimeHistory) -> String {
    let mut s = CSV_COLUMNS.join(",");
    for (d, _) in &h.outputs {
        s.push(',');
        s.push_str(&d.column());
    }
    s.push('\n');
    for k in 0..h.len() {
        s.push_str(&format!(
            "{:e},{:e},{:e},{:e}",
            k as f64 * h.dt_s,
            h.ground_accel_mm_s2[k],
            h.specimen_force_kn[k],
            h.interface_mm[k]
        ));
        for (_, v) in &h.outputs {
            s.push_str(&format!(",{:e}", v[k]));
        }
        s.push('\n');
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    const DT: f64 = 1.0 / 2048.0;

    fn sample(rows: usize) -> TimeHistory {
        let w = |k: usize, a: f64| (k as f64 * a).sin();
        TimeHistory {
            source: PathBuf::from("h.csv"),
            dt_s: DT,
            ground_accel_mm_s2: (0..rows).map(|k| 1000.0 * w(k, 0.01)).collect(),
            specimen_force_kn: (0..rows).map(|k| 50.0 * w(k, 0.02)).collect(),
            interface_mm: (0..rows).map(|k| w(k, 0.02)).collect(),
            outputs: vec![
                (
                    OutputDof { node: 1, dof: 1 },
                    (0..rows).map(|k| w(k, 0.03)).collect(),
                ),
                (
                    OutputDof { node: 3, dof: 1 },
                    (0..rows).map(|k| w(k, 0.04)).collect(),
                ),
            ],
            // As read back: the header on line 1, a row a line.
            row_line: (2..rows + 2).collect(),
        }
    }

    fn err(text: &str) -> String {
        parse_csv(text, Path::new("h.csv"), DT)
            .unwrap_err()
            .to_string()
    }

    #[test]
    fn csv_round_trips_exactly() {
        let h = sample(300);
        let back = parse_csv(&to_csv(&h), Path::new("h.csv"), DT).unwrap();
        assert_eq!(back, h);
        assert_eq!(back.row_at(0), "h.csv: line 2");
        let made = TimeHistory {
            row_line: Vec::new(),
            ..back.clone()
        };
        assert_eq!(made.row_at(9), "h.csv: data row 10");
        assert_eq!(
            back.output(OutputDof { node: 3, dof: 1 }).unwrap().len(),
            300
        );
    }

    #[test]
    fn csv_errors_name_the_file_and_the_row() {
        let good = to_csv(&sample(20));
        let rows: Vec<&str> = good.lines().collect();
        // A gap: row 6 (line 7) left out.
        let gap: String = rows
            .iter()
            .enumerate()
            .filter(|(i, _)| *i != 6)
            .map(|(_, r)| format!("{r}\n"))
            .collect();
        let e = err(&gap);
        assert!(e.starts_with("h.csv: line 7:") && e.contains("gap"), "{e}");
        // Another rate: the same rows at 4096 Hz.
        let h = TimeHistory {
            dt_s: DT / 2.0,
            ..sample(20)
        };
        let e = err(&to_csv(&h));
        assert!(e.contains("h.csv") && e.contains("runs at 2048 Hz"), "{e}");
        assert!(e.contains("--dt 0.00048828125`"), "{e}");
        // A short row.
        let mut short = rows.clone();
        short[5] = "0.00244140625,1,2,3";
        let e = err(&(short.join("\n") + "\n"));
        assert!(e.contains("h.csv: line 6: 4 columns, expected 6"), "{e}");
        // An empty file, or one of blank lines.
        for empty in ["", "\n\n  \n"] {
            let e = err(empty);
            assert!(e.starts_with("h.csv: empty"), "{e}");
        }
        // NaN and a non-number.
        let mut nan = rows.clone();
        let mut f: Vec<&str> = rows[9].split(',').collect();
        f[1] = "NaN";
        let bad = f.join(",");
        nan[9] = &bad;
        let e = err(&(nan.join("\n") + "\n"));
        assert!(
            e.contains("line 10: column `ground_accel_mm_s2` is not finite"),
            "{e}"
        );
        let mut word = rows.clone();
        let w = rows[3].replacen(",", ",x", 1);
        word[3] = &w;
        assert!(err(&(word.join("\n") + "\n")).contains("line 4: column `ground_accel_mm_s2`"));
        // Missing and unknown columns, a column twice.
        let e = err("time_s,ground_accel_mm_s2,interface_mm\n0,0,0\n");
        assert!(e.contains("column 3 must be `specimen_force_kn`"), "{e}");
        let e = err("time_s,ground_accel_mm_s2,specimen_force_kn,interface_mm,floor1\n");
        assert!(
            e.contains("column 5 `floor1` is not out_<NODE>_<DOF>_mm"),
            "{e}"
        );
        let e =
            err("time_s,ground_accel_mm_s2,specimen_force_kn,interface_mm,out_1_1_mm,out_1_1_mm\n");
        assert!(e.contains("given twice"), "{e}");
        assert!(err("0,1,2,3\n").contains("column 1 must be `time_s`"));
        let e = err(&rows[..2].join("\n"));
        assert!(e.contains("1 data rows"), "{e}");
    }

    #[test]
    fn recorder_dir_reads_and_checks_its_shape() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path();
        let write = |name: &str, rows: &[(f64, f64)]| {
            let t: String = rows.iter().map(|(a, b)| format!("{a:e} {b:e}\n")).collect();
            std::fs::write(p.join(name), t).unwrap();
        };
        let rows = |f: f64| -> Vec<(f64, f64)> {
            (1..=50).map(|k| (k as f64 * DT, f * k as f64)).collect()
        };
        write("ground_accel.out", &rows(1.0));
        let e = read_recorder_dir(p, RecorderUnits::SI, DT)
            .unwrap_err()
            .to_string();
        assert!(e.contains("specimen_force.out: missing"), "{e}");
        write("specimen_force.out", &rows(1000.0));
        write("interface_disp.out", &rows(0.001));
        write("out_7_1.out", &rows(0.002));
        let h = read_recorder_dir(p, RecorderUnits::SI, DT).unwrap();
        assert_eq!(h.len(), 50);
        assert!((h.specimen_force_kn[1] - 2.0).abs() < 1e-12);
        assert!((h.interface_mm[1] - 2.0).abs() < 1e-12);
        assert!((h.ground_accel_mm_s2[1] - 2000.0).abs() < 1e-9);
        assert_eq!(h.outputs[0].0, OutputDof { node: 7, dof: 1 });
        // A recorder of two DOFs in one file: the wrong shape, named by file and line.
        std::fs::write(p.join("out_7_1.out"), "0.00048828125 1 2\n").unwrap();
        let e = read_recorder_dir(p, RecorderUnits::SI, DT)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("out_7_1.out: line 1: 3 columns, expected 2"),
            "{e}"
        );
        // Fewer rows than the ground file.
        write("out_7_1.out", &rows(1.0)[..40]);
        let e = read_recorder_dir(p, RecorderUnits::SI, DT)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("out_7_1.out: line 41: the file ends after 40 rows"),
            "{e}"
        );
        // More rows, and an empty file.
        let mut more = rows(1.0);
        more.push((51.0 * DT, 0.0));
        write("out_7_1.out", &more);
        let e = read_recorder_dir(p, RecorderUnits::SI, DT)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("out_7_1.out: line 51: a row past the 50 rows"),
            "{e}"
        );
        write("out_7_1.out", &[]);
        let e = read_recorder_dir(p, RecorderUnits::SI, DT)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("out_7_1.out: line 1: the file ends after 0 rows"),
            "{e}"
        );
        // Rows read are placed by the interface's file.
        write("out_7_1.out", &rows(1.0));
        let h = read_recorder_dir(p, RecorderUnits::SI, DT).unwrap();
        assert_eq!(h.row_line.len(), 50);
        let at = h.row_at(4);
        assert!(at.ends_with("interface_disp.out: line 5"), "{at}");
    }

    #[test]
    fn printed_resolution_is_half_the_last_digit() {
        for (token, want) in [
            ("0.000488281", 0.5e-9),
            ("48.8281", 0.5e-4),
            ("4.88281e-05", 0.5e-10),
            ("50", 2.5e-4),
            ("1E3", 5e-3),
            ("1.00000E3", 5e-3),
            ("1234.56", 5e-3),
            (" 0.00048828125 ", 0.5e-11),
            // Shorter than 6 significant digits: as precise as 6 at least.
            ("0", 0.0),
            ("1", 5e-6),
            ("0.5", 2.5e-6),
        ] {
            let got = printed_resolution(token);
            assert!(
                (got - want).abs() <= 1e-9 * want,
                "{token}: {got} against {want}"
            );
        }
    }

    /// C's `%g` with 6 significant digits, as OpenSees's recorders print without `-precision`.
    fn six_digits(v: f64) -> String {
        if v == 0.0 {
            return "0".into();
        }
        let e = v.abs().log10().floor() as i32;
        if !(-5..6).contains(&e) {
            let s = format!("{v:.5e}");
            return s;
        }
        let decimals = usize::try_from(5 - e).unwrap_or(0);
        let s = format!("{v:.decimals$}");
        if s.contains('.') {
            s.trim_end_matches('0').trim_end_matches('.').to_string()
        } else {
            s
        }
    }

    #[test]
    fn a_recorder_run_printed_with_six_digits_reads_and_a_missing_row_is_refused() {
        // One minute at 2048 Hz: past 10 s the times are printed to 1e-4 s, a fifth of a step.
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path();
        let n = 60 * 2048;
        let write = |name: &str, skip: Option<usize>| {
            let t: String = (1..=n)
                .filter(|k| Some(*k) != skip)
                .map(|k| {
                    let t = k as f64 * DT;
                    format!("{} {}\n", six_digits(t), six_digits((t * 3.0).sin()))
                })
                .collect();
            std::fs::write(p.join(name), t).unwrap();
        };
        for f in RECORDER_FILES {
            write(f, None);
        }
        let h = read_recorder_dir(p, RecorderUnits::MM_KN, DT).unwrap();
        assert_eq!(h.len(), n);
        // A row missing at 50 s: its line is named.
        write("interface_disp.out", Some(50 * 2048));
        let e = read_recorder_dir(p, RecorderUnits::MM_KN, DT)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains(&format!("interface_disp.out: line {}: time", 50 * 2048)),
            "{e}"
        );
        write("interface_disp.out", None);
        write("ground_accel.out", Some(50 * 2048));
        let e = read_recorder_dir(p, RecorderUnits::MM_KN, DT)
            .unwrap_err()
            .to_string();
        assert!(e.contains(&format!("line {}", 50 * 2048)), "{e}");
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(256))]
        /// Arbitrary text: a history or an error, never a panic; an accepted history is uniform,
        /// finite and of equal lengths.
        #[test]
        fn any_text_reads_or_is_refused(text in "[-0-9.,e_a-z\n NaN]{0,400}") {
            if let Ok(h) = parse_csv(&text, Path::new("p.csv"), DT) {
                prop_assert!(h.len() >= 2);
                prop_assert_eq!(h.specimen_force_kn.len(), h.len());
                prop_assert_eq!(h.interface_mm.len(), h.len());
                for (_, v) in &h.outputs {
                    prop_assert_eq!(v.len(), h.len());
                }
                prop_assert!(h.ground_accel_mm_s2.iter().all(|v| v.is_finite()));
            }
        }

        /// A good file with one cell replaced: read exactly, or refused naming that cell's line.
        #[test]
        fn one_bad_cell_is_named(row in 0usize..30, col in 0usize..6, cell in "[-0-9.eNaninf]{0,8}") {
            let good = to_csv(&sample(30));
            let mut rows: Vec<String> = good.lines().map(str::to_string).collect();
            let mut fields: Vec<String> = rows[row + 1].split(',').map(str::to_string).collect();
            fields[col] = cell;
            rows[row + 1] = fields.join(",");
            let text = rows.join("\n");
            match parse_csv(&text, Path::new("p.csv"), DT) {
                Ok(h) => prop_assert_eq!(h.len(), 30),
                Err(e) => {
                    let s = e.to_string();
                    prop_assert!(s.starts_with("p.csv: "), "{}", s);
                    // A bad time moves the file's mean step: the uneven step may show anywhere.
                    let named = s.contains(&format!("line {}:", row + 2))
                        || (col == 0 && (s.contains("line ") || s.contains("runs at 2048 Hz")));
                    prop_assert!(named, "{}", s);
                }
            }
        }
    }
}
