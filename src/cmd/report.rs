//! `rths report RUN.csv`: the figures, metrics and plots of `rths simulate` for a recording of a
//! test on a board (`rths link run --out RUN.csv`). The reference is computed here, on the host,
//! from what the recording's header names (the record, its scale, the structure), never from
//! anything the board measured; the controller's series come from the recording.

use std::path::PathBuf;

use anyhow::Context;
use rths_core::params::DT_S;
use rths_core::supervisor::FaultReason;
use rths_hal_sim::{BoucWen, Specimen};

use crate::cmd::analyze::load_motion;
use crate::link_host::{self, Recording, RecordingRow};
use crate::studies::nonlinear::scenario::{self as nl, LengthScale, SimScenario, StructureCase};
use crate::studies::scenario::{self, RunHistory, ScenarioId, ScenarioReport, ScenarioRun};
use crate::studies::study::{self, StudyJson};

/// Arguments of `rths report`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The recording (`rths link run --out`), with its header.
    pub recording: PathBuf,
    /// The scenario id of the figures (default: the header's, from the device's model kind).
    #[arg(long)]
    pub scenario: Option<ScenarioId>,
    /// A structure recording (`rths link run --structure`): read the structure from this file
    /// instead of the header's path (refused unless its checksum is the header's).
    #[arg(long, value_name = "S.json")]
    pub structure: Option<PathBuf>,
    /// Output directory for `history.csv` and the figure (as `rths simulate --out`).
    #[arg(long, value_name = "DIR")]
    pub out: Option<PathBuf>,
    /// Print one JSON object on stdout and nothing else.
    #[arg(long)]
    pub json: bool,
}

/// The JSON of `rths report`: `rths simulate`'s study object, and the recording's header.
#[derive(Debug, serde::Serialize)]
struct ReportJson {
    #[serde(flatten)]
    study: StudyJson,
    /// The recording's header fields.
    recording: std::collections::BTreeMap<String, String>,
    /// A structure recording: the structure scored against, and what the figures leave out.
    #[serde(skip_serializing_if = "Option::is_none")]
    structure: Option<StructureScoring>,
}

/// How a structure recording (`rths link run --structure`) was scored.
#[derive(Debug, Clone, serde::Serialize)]
pub struct StructureScoring {
    /// The structure's name.
    pub name: String,
    /// The structure file read (the header's path or `--structure`).
    pub file: String,
    /// Its checksum (`structure_checksum`, the header's).
    pub checksum: String,
    /// The length scale L of the run (prototype over rig).
    pub length_scale: f64,
    /// cos θ between the specimen's DOF and the actuator.
    pub cos_theta: f64,
    /// The ticks scored: the record the board played (the reference is cut there).
    pub ticks: usize,
    /// What `rths simulate --structure` scores that this report does not, and why.
    pub window: &'static str,
    /// The reference's peak ductility over all stories (`null`: a linear structure), as `rths
    /// simulate --structure` gives it (computed here, record and free vibration).
    pub peak_ductility: Option<f64>,
    /// The reference's peak ductility at the specimen's story.
    pub peak_ductility_specimen_story: Option<f64>,
    /// The structure figures the recording cannot give (`null`, never estimated).
    pub peak_ductility_model: Option<f64>,
    /// As [`Self::peak_ductility_model`].
    pub residual_drift_mm: Option<f64>,
    /// As [`Self::peak_ductility_model`].
    pub residual_drift_error_pct: Option<f64>,
    /// Why those are absent.
    pub absent: &'static str,
    /// Why the reference is beyond the rig at this length scale, if it is.
    pub beyond_rig: Option<String>,
}

/// The window of a structure recording's figures.
const STRUCTURE_WINDOW: &str = "the record the board played; `rths simulate --structure` also \
     scores the 10 s of free vibration after it, which the board does not run";

/// Why a structure recording has no story figures.
const STRUCTURE_ABSENT: &str = "story drifts, residual drift and ductility need the model's \
     story drifts, which a board's recording does not carry (it records the specimen's DOF only)";

/// The host history of a recording: row k as `scenario::simulate` fills it (time k·Δt, ü_g and the
/// reference at k, the command and target the controller produced at tick k−1, 0 at k = 0, the
/// target held when not finite, the DAQ reading of tick k). Needs every tick from 0
/// (`--telemetry-every 1`): rows up to the record's end, or up to a fault (the figures then stop there). Returns
/// the history and the supervisor's stop (reason, time) if it tripped within the record. A sample
/// that is not finite before any fault makes the run not clean: refused, naming the tick, its time
/// and the channel (the supervisor stops on such a sample, so the recording cannot be what the
/// board read; figures over it would be blank).
pub fn history_of(
    rows: &[RecordingRow],
    ag_mm_s2: &[f64],
    reference_mm: &[f64],
) -> anyhow::Result<(RunHistory, Option<(String, f64)>)> {
    let n = ag_mm_s2.len();
    if let Some(u) = link_host::first_unclean_sample(&rows[..rows.len().min(n)]) {
        anyhow::bail!(
            "the run is not clean: {} is {} at tick {} (t = {:.4} s, state {}): the supervisor \
             stops on a non-finite sample, so this recording is not what the board read and has \
             no figures",
            u.channel,
            u.value,
            u.row,
            u.row as f64 * DT_S,
            u.state
        );
    }
    let mut h = RunHistory::default();
    let mut stop = None;
    let (mut command, mut target) = (0.0, 0.0);
    for k in 0..n {
        let Some(r) = rows.get(k) else {
            if stop.is_some() {
                break;
            }
            anyhow::bail!(
                "the recording has {} rows, the record {n} ticks: incomplete (no fault recorded)",
                rows.len()
            );
        };
        if r.tick as usize != k || r.seq as usize != k {
            anyhow::bail!(
                "row {k} is record {} of tick {}: the report needs every tick from 0 (record with \
                 --telemetry-every 1, without gaps)",
                r.seq,
                r.tick
            );
        }
        h.time_s.push(k as f64 * DT_S);
        h.ground_accel_mm_s2.push(ag_mm_s2[k]);
        h.reference_mm.push(reference_mm[k]);
        h.target_mm.push(target);
        h.command_mm.push(command);
        h.measured_mm.push(r.measured_mm);
        h.measured_force_kn.push(r.force_kn);
        command = r.command_mm;
        if r.target_mm.is_finite() {
            target = r.target_mm;
        }
        if let (Some(name), None) = (r.state.strip_prefix("fault-"), &stop) {
            let reason = FaultReason::ALL
                .iter()
                .find(|(_, _, n)| *n == name)
                .map_or_else(|| name.to_string(), |(r, _, _)| format!("{r:?}"));
            stop = Some((reason, k as f64 * DT_S));
        }
    }
    Ok((h, stop))
}

/// The figures of a recording, and the run (history) they come from.
pub fn analyze(
    rec: &Recording,
    scenario: Option<ScenarioId>,
    structure: Option<&std::path::Path>,
) -> anyhow::Result<ScenarioRun> {
    let hd = &rec.header;
    if hd.get("source") == Some("site") {
        return analyze_site(rec);
    }
    let field = |k: &str| {
        hd.get(k).with_context(|| {
            format!("the recording's header has no `{k}` (record it with `rths link run`)")
        })
    };
    if hd.get("structure").is_some_and(|s| s != "paper") {
        return analyze_structure(rec, structure, scenario).map(|(run, _)| run);
    }
    if let Some(p) = structure {
        anyhow::bail!(
            "--structure {}: the recording is of the paper's frame (no structure part)",
            p.display()
        );
    }
    let id: ScenarioId = match scenario {
        Some(id) => id,
        None => field("scenario")?.parse()?,
    };
    let motion = recorded_motion(rec)?;
    if field("structure")? != "paper" {
        anyhow::bail!("unknown structure `{}`", field("structure")?);
    }
    let specimen = match field("specimen")? {
        "linear" => Specimen::Linear,
        "bouc-wen" => Specimen::BoucWen(BoucWen::default()),
        other => anyhow::bail!("unknown specimen `{other}`"),
    };
    let f: f64 = field("specimen_stiffness_factor")?
        .parse()
        .context("header `specimen_stiffness_factor`")?;
    let ag = motion.resample_mm_s2(DT_S);
    // The evaluation's reference: the structure's response, computed here.
    let reference = study::reference_for(&ag, specimen, f)?;
    let (history, stop) = history_of(&rec.rows, &ag, &reference)?;
    let report: ScenarioReport = scenario::figures(id, &history, stop);
    Ok(ScenarioRun { report, history })
}

/// Header field `k` of a recording, or an error naming it.
fn header_field<'a>(rec: &'a Recording, k: &str) -> anyhow::Result<&'a str> {
    rec.header.get(k).with_context(|| {
        format!("the recording's header has no `{k}` (record it with `rths link run`)")
    })
}

/// The ground motion the header names, checked against the record the device played (same
/// samples, step and scale).
fn recorded_motion(rec: &Recording) -> anyhow::Result<crate::machinery::motion::GroundMotion> {
    let field = |k: &str| header_field(rec, k);
    let scale: f64 = field("scale")?.parse().context("header `scale`")?;
    let named = field("motion")?;
    if std::path::Path::new(named).exists() {
        // A file named by the header is read within a limit (never a device that never ends).
        link_host::check_named_file("motion", std::path::Path::new(named))?;
    }
    let motion = load_motion(Some(named))?.scaled(scale);
    let sum = format!(
        "{:08x}",
        rths_link::record_checksum(&motion.accel_g, motion.dt_s)
    );
    let want = field("record_checksum")?;
    if sum != want {
        anyhow::bail!(
            "the ground motion `{named}` × {scale} has checksum {sum}, the device played {want}: \
             not the record of this recording"
        );
    }
    Ok(motion)
}

/// The figures of a structure recording (`rths link run --structure S.json --rig RIG.json`):
/// the structure read from `given` or the header's path (its checksum must be the header's),
/// its reference computed here over the record the board played (as `rths simulate
/// --structure` computes it, cut at the record's end), the recording's rig-scale series brought
/// to the prototype as `run_hybrid` does (× L for the command and the measured displacement,
/// × cos θ for the target), and the study's figures of them as `score` computes them. The
/// story figures are absent: the recording has no story drifts.
pub fn analyze_structure(
    rec: &Recording,
    given: Option<&std::path::Path>,
    scenario: Option<ScenarioId>,
) -> anyhow::Result<(ScenarioRun, StructureScoring)> {
    let field = |k: &str| header_field(rec, k);
    if let Some(id) = scenario {
        anyhow::bail!(
            "--scenario {id}: a structure recording is scored as the scenario the board ran \
             (the header's `{}`)",
            field("scenario").unwrap_or("?")
        );
    }
    let named = field("structure")?;
    let want = field("structure_checksum")?;
    let path = given.unwrap_or(std::path::Path::new(named));
    link_host::check_named_file("structure", path)
        .with_context(|| format!("structure file {}", path.display()))?;
    let text = std::fs::read_to_string(path)
        .with_context(|| format!("reading structure file {}", path.display()))?;
    let sum = rths_files::nl_model_file::structure_checksum(&text)
        .with_context(|| format!("structure file {}", path.display()))?;
    if sum != want {
        anyhow::bail!(
            "the structure file {} has checksum {sum}, the recording's structure `{named}` had \
             {want}: not the structure of this recording",
            path.display()
        );
    }
    let length: f64 = field("length_scale")?
        .parse()
        .context("header `length_scale`")?;
    let length = LengthScale::new(length)?;
    let named_sc = field("scenario")?;
    let sc = match named_sc.parse::<SimScenario>() {
        Ok(sc @ (SimScenario::NlOnline | SimScenario::FeOnlineLead)) => sc,
        _ => anyhow::bail!(
            "a structure recording of scenario {named_sc}: `rths report` scores nl-online and \
             fe-online-lead recordings (a structure part with --rig); an imported structure's \
             (meta-online) reference is not computed here yet, and a structure part without \
             --rig has no rig to score"
        ),
    };
    if crate::machinery::imported::file::is_imported(&text) {
        anyhow::bail!(
            "{} is an imported structure: its reference (`rths simulate --structure`'s \
             imported FE) is not computed by `rths report` yet",
            path.display()
        );
    }
    let structure = rths_files::structure_file::Structure::from_json(&text)
        .with_context(|| format!("structure file {}", path.display()))?;
    nl::check_applies(sc, &structure)?;
    let ag = recorded_motion(rec)?.resample_mm_s2(DT_S);
    // The evaluation's reference: the whole structure's response, computed here (never read
    // from the board).
    let case = StructureCase::new(structure, &ag)?.with_length_scale(length);
    let n = ag.len();
    let (mut history, stop) = history_of(&rec.rows, &ag, &case.reference_mm[..n])?;
    // The rig's series in the structure's actuator coordinates, as `run_hybrid` pushes them.
    let scale = length.specimen_scale();
    for x in &mut history.target_mm {
        *x *= case.cos_theta;
    }
    for x in history
        .command_mm
        .iter_mut()
        .chain(history.measured_mm.iter_mut())
    {
        *x = scale.prototype_disp_mm(*x);
    }
    let report = scenario::figures_of_series(
        &sc.to_string(),
        sc.uses_rig(),
        &history.target_mm,
        &history.command_mm,
        &history.measured_mm,
        &history.reference_mm,
        stop,
    );
    let (peak_ductility, peak_ductility_specimen_story) = nl::reference_ductility(&case);
    let scoring = StructureScoring {
        peak_ductility,
        peak_ductility_specimen_story,
        name: case.structure.name().to_string(),
        file: path.display().to_string(),
        checksum: sum,
        length_scale: length.get(),
        cos_theta: case.cos_theta,
        ticks: history.len(),
        window: STRUCTURE_WINDOW,
        peak_ductility_model: None,
        residual_drift_mm: None,
        residual_drift_error_pct: None,
        absent: STRUCTURE_ABSENT,
        beyond_rig: case.beyond_rig(),
    };
    Ok((ScenarioRun { report, history }, scoring))
}

/// The figures of an `rths site` recording (docs/site.md): the structure lives in the client's
/// analysis, so its reference is the analysis's own targets (the rows while the test ran): the
/// measured figures are the actuator's tracking of them; the target's NRMSE is not a figure here.
fn analyze_site(rec: &Recording) -> anyhow::Result<ScenarioRun> {
    let running = rec
        .rows
        .iter()
        .rposition(|r| r.state == "running")
        .map_or(0, |i| i + 1);
    let rows = &rec.rows[..running];
    let zeros = vec![0.0; rows.len()];
    let (mut history, _) = history_of(rows, &zeros, &zeros)?;
    history.reference_mm = history.target_mm.clone();
    let stop = rec
        .header
        .get("stop_reason")
        .map(|r| (r.to_string(), rows.len() as f64 * DT_S));
    let mut report = scenario::figures_of_series(
        "site",
        true,
        &history.target_mm,
        &history.command_mm,
        &history.measured_mm,
        &history.reference_mm,
        stop,
    );
    report.nrmse_pct = None;
    Ok(ScenarioRun { report, history })
}

/// Run `rths report`.
pub fn run(args: Args) -> anyhow::Result<()> {
    let rec = link_host::read_recording_file(&args.recording)
        .with_context(|| format!("recording {}", args.recording.display()))?;
    let is_structure = rec.header.get("source") != Some("site")
        && rec.header.get("structure").is_some_and(|s| s != "paper");
    let (run, scoring) = if is_structure {
        let (run, scoring) = analyze_structure(&rec, args.structure.as_deref(), args.scenario)
            .with_context(|| format!("recording {}", args.recording.display()))?;
        (run, Some(scoring))
    } else {
        let run = analyze(&rec, args.scenario, args.structure.as_deref())
            .with_context(|| format!("recording {}", args.recording.display()))?;
        (run, None)
    };
    let id = &run.report.id;
    let motion = rec.header.get("motion_name").or(rec.header.get("motion"));
    if let Some(dir) = &args.out {
        std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
        run.history.write_csv(&dir.join("history.csv"))?;
        study::plot_run(
            &run,
            &dir.join(format!("{id}.png")),
            &format!(
                "{id} ({}, recorded over the link: {})",
                motion.unwrap_or("?"),
                rec.header.get("link").unwrap_or("?")
            ),
        )?;
    }
    if args.json {
        let json = ReportJson {
            study: StudyJson {
                scenarios: vec![run.report.clone()],
                lr_coefficients: Vec::new(),
                lr_condition_number: None,
                specimen_sweep: None,
            },
            recording: rec.header.fields.iter().cloned().collect(),
            structure: scoring,
        };
        crate::outln!("{}", serde_json::to_string(&json)?);
        return crate::cmd::RunStopped::check(&run.report);
    }
    crate::outln!(
        "scenario            {id} ({}, recorded: model {} {}, record {})",
        motion.unwrap_or("?"),
        rec.header.get("model_kind").unwrap_or("?"),
        rec.header.get("model_checksum").unwrap_or("?"),
        rec.header.get("record_checksum").unwrap_or("?"),
    );
    crate::cmd::simulate::print_figures(&run.report);
    if let Some(st) = &scoring {
        crate::outln!(
            "structure           {} ({}, checksum {}), length scale {}, cos θ {}",
            st.name,
            st.file,
            st.checksum,
            st.length_scale,
            st.cos_theta
        );
        crate::outln!("scored              {} ticks: {}", st.ticks, st.window);
        if let (Some(all), Some(specimen)) = (st.peak_ductility, st.peak_ductility_specimen_story) {
            crate::outln!(
                "reference ductility {all:.4} (peak, all stories), {specimen:.4} (specimen's story)"
            );
        }
        crate::outln!(
            "story figures       absent (ductility, residual drift): {}",
            st.absent
        );
        if let Some(b) = &st.beyond_rig {
            crate::outln!("beyond the rig       {b}");
        }
    }
    if let Some(dir) = &args.out {
        crate::outln!("wrote {}", dir.join("history.csv").display());
        crate::outln!("wrote {}", dir.join(format!("{id}.png")).display());
    }
    crate::cmd::RunStopped::check(&run.report)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::link_host::read_recording;

    fn row(k: u32, state: &str, command_mm: f64) -> RecordingRow {
        RecordingRow {
            seq: k,
            tick: k,
            state: state.into(),
            command_mm,
            target_mm: command_mm,
            measured_mm: 0.5 * command_mm,
            force_kn: 0.1,
        }
    }

    #[test]
    fn the_history_of_a_recording_is_the_host_simulations_rows() -> anyhow::Result<()> {
        let ag = [1.0, 2.0, 3.0, 4.0];
        let reference = [0.0, 0.1, 0.2, 0.3];
        let rows: Vec<_> = (0..6).map(|k| row(k, "running", k as f64 + 1.0)).collect();
        let (h, stop) = history_of(&rows, &ag, &reference)?;
        assert!(stop.is_none());
        assert_eq!(h.len(), 4);
        // Row k: the command and target of record k−1 (0 at k = 0), the DAQ reading of record k.
        assert_eq!(h.command_mm, [0.0, 1.0, 2.0, 3.0]);
        assert_eq!(h.target_mm, [0.0, 1.0, 2.0, 3.0]);
        assert_eq!(h.measured_mm, [0.5, 1.0, 1.5, 2.0]);
        assert_eq!(h.reference_mm, reference);
        assert_eq!(h.ground_accel_mm_s2, ag);
        assert_eq!(h.time_s[2], 2.0 * DT_S);
        Ok(())
    }

    #[test]
    fn a_fault_stops_the_figures_and_bad_recordings_are_refused() {
        let ag = [0.0; 4];
        let reference = [0.0; 4];
        let mut rows: Vec<_> = (0..2).map(|k| row(k, "running", 0.0)).collect();
        rows.push(row(2, "fault-NonFiniteSample", 0.0));
        let (_, stop) = history_of(&rows, &ag, &reference).unwrap();
        assert_eq!(stop, Some(("NonFiniteSample".to_string(), 2.0 * DT_S)));
        // Too short without a fault, decimated, a gap.
        let short: Vec<_> = (0..3).map(|k| row(k, "running", 0.0)).collect();
        assert!(history_of(&short, &ag, &reference).is_err());
        let decimated: Vec<_> = (0..4).map(|k| row(k * 2, "running", 0.0)).collect();
        assert!(history_of(&decimated, &ag, &reference).is_err());
        let mut gap: Vec<_> = (0..5).map(|k| row(k, "running", 0.0)).collect();
        gap.remove(1);
        assert!(history_of(&gap, &ag, &reference).is_err());
    }

    #[test]
    fn a_non_finite_sample_before_any_fault_makes_the_run_not_clean() {
        let ag = [0.0; 4];
        let reference = [0.0; 4];
        let mut rows: Vec<_> = (0..4).map(|k| row(k, "running", 1.0)).collect();
        rows[2].measured_mm = f64::NAN;
        let e = history_of(&rows, &ag, &reference).unwrap_err().to_string();
        for part in ["not clean", "measured_mm is NaN", "tick 2", "t = 0.0010 s"] {
            assert!(e.contains(part), "`{part}` not in: {e}");
        }
        rows[2].measured_mm = 0.5;
        rows[1].force_kn = f64::INFINITY;
        let e = history_of(&rows, &ag, &reference).unwrap_err().to_string();
        assert!(e.contains("force_kn is inf at tick 1"), "{e}");
        // After the supervisor's trip a non-finite sample is what stopped it: the figures stop.
        rows[1].state = "fault-NonFiniteSample".into();
        let (_, stop) = history_of(&rows, &ag, &reference).unwrap();
        assert_eq!(stop, Some(("NonFiniteSample".to_string(), DT_S)));
    }

    #[test]
    fn a_recording_without_a_header_or_of_another_record_is_refused() {
        let csv = format!(
            "{}\n0,0,0.0,running,0.0,0.0,0.0,0.0\n",
            link_host::CSV_HEADER
        );
        let rec = read_recording(&csv).unwrap();
        let e = analyze(&rec, None, None).unwrap_err().to_string();
        assert!(e.contains("no `scenario`"), "{e}");
        let text = format!(
            "# format: rths-recording 1\n# scenario: lr-online\n# motion: el-centro\n# scale: 1.0\n\
             # record_checksum: 00000000\n{csv}"
        );
        let e = analyze(&read_recording(&text).unwrap(), None, None)
            .unwrap_err()
            .to_string();
        assert!(e.contains("not the record of this recording"), "{e}");
    }

    #[test]
    fn a_recording_naming_a_file_that_never_ends_is_refused_unread() {
        if !std::path::Path::new("/dev/zero").exists() {
            eprintln!("SKIPPED: /dev/zero (not on this system)");
            return;
        }
        let text = format!(
            "# format: rths-recording 1\n# scenario: lr-online\n# motion: /dev/zero\n# scale: 1.0\n\
             # record_checksum: 00000000\n{}\n",
            link_host::CSV_HEADER
        );
        let e = analyze(&read_recording(&text).unwrap(), None, None)
            .unwrap_err()
            .to_string();
        assert!(e.contains("not a regular file"), "{e}");
    }
    /// A structure recording's header (`rths link run --structure`), with `drop` left out and
    /// `checksum` as its structure checksum.
    fn structure_recording(drop: &str, checksum: Option<&str>) -> Recording {
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("data/structures/shear3-yielding.json");
        let text = std::fs::read_to_string(&path).unwrap();
        let sum = rths_files::nl_model_file::structure_checksum(&text).unwrap();
        let el = crate::machinery::motion::GroundMotion::el_centro();
        let fields = [
            ("scenario", "nl-online".to_string()),
            ("motion", "el-centro".to_string()),
            ("scale", "1.0".to_string()),
            (
                "record_checksum",
                format!("{:08x}", rths_link::record_checksum(&el.accel_g, el.dt_s)),
            ),
            ("structure", path.display().to_string()),
            ("structure_checksum", checksum.map_or(sum, str::to_string)),
            ("length_scale", "2.0".to_string()),
        ];
        let mut head = String::from("# format: rths-recording 1\n");
        for (k, v) in fields.iter().filter(|(k, _)| *k != drop) {
            head.push_str(&format!("# {k}: {v}\n"));
        }
        read_recording(&format!(
            "{head}{}\n0,0,0.0,running,0.0,0.0,0.0,0.0\n",
            link_host::CSV_HEADER
        ))
        .unwrap()
    }

    #[test]
    fn a_structure_recording_of_another_structure_file_is_refused() {
        let rec = structure_recording("", Some("fnv1a64:0000000000000000"));
        let e = format!("{:#}", analyze_structure(&rec, None, None).unwrap_err());
        for part in [
            "has checksum fnv1a64:",
            "not the structure of this recording",
        ] {
            assert!(e.contains(part), "`{part}` not in: {e}");
        }
        // `--structure` of another file than the one recorded: refused the same way.
        let other = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("data/structures/shear8-yielding.json");
        let rec = structure_recording("", None);
        let e = format!(
            "{:#}",
            analyze_structure(&rec, Some(&other), None).unwrap_err()
        );
        assert!(e.contains("not the structure of this recording"), "{e}");
        assert!(e.contains("shear8-yielding.json"), "{e}");
        // Through `analyze` too (a structure recording is never scored as the paper's frame).
        let e = format!("{:#}", analyze(&rec, None, Some(&other)).unwrap_err());
        assert!(e.contains("not the structure of this recording"), "{e}");
    }

    #[test]
    fn a_structure_recording_without_its_header_fields_is_refused() {
        for field in [
            "structure_checksum",
            "length_scale",
            "scenario",
            "record_checksum",
        ] {
            let rec = structure_recording(field, None);
            let e = format!("{:#}", analyze_structure(&rec, None, None).unwrap_err());
            assert!(e.contains(&format!("no `{field}`")), "{field}: {e}");
        }
        // A structure part run without --rig (`structure-nl`): no hybrid figures, refused.
        let mut rec = structure_recording("", None);
        for f in rec.header.fields.iter_mut() {
            if f.0 == "scenario" {
                f.1 = "structure-nl".into();
            }
        }
        let e = format!("{:#}", analyze_structure(&rec, None, None).unwrap_err());
        assert!(
            e.contains("scenario structure-nl: `rths report` scores"),
            "{e}"
        );
        // A scenario other than the board's is refused, not rescored.
        let rec = structure_recording("", None);
        let e = format!(
            "{:#}",
            analyze_structure(&rec, None, Some(ScenarioId::FeOnlineAts)).unwrap_err()
        );
        assert!(e.contains("the header's `nl-online`"), "{e}");
        // A structure file that is not there.
        let mut rec = structure_recording("", None);
        for f in rec.header.fields.iter_mut() {
            if f.0 == "structure" {
                f.1 = "/nonexistent/s.json".into();
            }
        }
        let e = format!("{:#}", analyze_structure(&rec, None, None).unwrap_err());
        assert!(e.contains("/nonexistent/s.json"), "{e}");
    }
}
