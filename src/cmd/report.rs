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
}

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
pub fn analyze(rec: &Recording, scenario: Option<ScenarioId>) -> anyhow::Result<ScenarioRun> {
    let hd = &rec.header;
    if hd.get("source") == Some("site") {
        return analyze_site(rec);
    }
    let field = |k: &str| {
        hd.get(k).with_context(|| {
            format!("the recording's header has no `{k}` (record it with `rths link run`)")
        })
    };
    let id: ScenarioId = match scenario {
        Some(id) => id,
        None => field("scenario")?.parse()?,
    };
    let scale: f64 = field("scale")?.parse().context("header `scale`")?;
    let named = field("motion")?;
    if std::path::Path::new(named).exists() {
        // A file named by the header is read within a limit (never a device that never ends).
        link_host::check_named_file("motion", std::path::Path::new(named))?;
    }
    let motion = load_motion(Some(named))?.scaled(scale);
    // The record the device played must be the one named: same samples, step and scale.
    let sum = format!(
        "{:08x}",
        rths_link::record_checksum(&motion.accel_g, motion.dt_s)
    );
    let want = field("record_checksum")?;
    if sum != want {
        anyhow::bail!(
            "the ground motion `{}` × {scale} has checksum {sum}, the device played {want}: \
             not the record of this recording",
            field("motion")?
        );
    }
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
    let run = analyze(&rec, args.scenario)
        .with_context(|| format!("recording {}", args.recording.display()))?;
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
        let e = analyze(&rec, None).unwrap_err().to_string();
        assert!(e.contains("no `scenario`"), "{e}");
        let text = format!(
            "# format: rths-recording 1\n# scenario: lr-online\n# motion: el-centro\n# scale: 1.0\n\
             # record_checksum: 00000000\n{csv}"
        );
        let e = analyze(&read_recording(&text).unwrap(), None)
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
        let e = analyze(&read_recording(&text).unwrap(), None)
            .unwrap_err()
            .to_string();
        assert!(e.contains("not a regular file"), "{e}");
    }
}
