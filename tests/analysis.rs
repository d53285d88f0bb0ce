//! Pure analysis of the prototype under the shipped records, the readers on the shipped files, and
//! the `rths analyze` binary end to end.

use std::path::Path;
use std::process::Command;

use rths::machinery::motion::{parse_at2, GroundMotion};
use rths::studies::analysis::{pure_response, Method, PureResponse, Summary, ANALYSIS_CSV_HEADER};
use rths_core::metrics::{nrmse_pct, peak_abs};
use rths_core::params::{Prototype, DT_S};

fn el_centro(method: Method) -> PureResponse {
    let ag = GroundMotion::try_el_centro().unwrap().resample_mm_s2(DT_S);
    pure_response(&Prototype::paper(), &ag, DT_S, method).unwrap()
}

#[test]
fn explicit_methods_match_newmark_on_el_centro() {
    let reference = el_centro(Method::Newmark);
    for method in [Method::Chang, Method::ChenRicles] {
        let r = el_centro(method);
        let e = nrmse_pct(&r.story_disp_mm, &reference.story_disp_mm).unwrap();
        eprintln!("{method} vs Newmark: NRMSE {e:.2e} %");
        assert!(e < 0.01, "{method}: NRMSE {e} % vs Newmark");
    }
}

#[test]
fn el_centro_peaks_match_design() {
    let p = Prototype::paper();
    let r = el_centro(Method::Newmark);
    assert_eq!(r.len(), 81_900); // floor(39.99 s · 2048) + 1
    let s = Summary::new(&p, &r, DT_S);
    eprintln!("{s}");
    // docs/design.md §2: x ≈ 17.76 mm, d ≈ 12.67 mm, brace velocity ≈ 266 mm/s.
    assert!((s.peak_story_disp_mm - 17.76).abs() < 0.05, "{s}");
    assert!((s.peak_brace_disp_mm - 12.67).abs() < 0.05, "{s}");
    assert!((s.peak_brace_vel_mm_s - 266.0).abs() < 2.0, "{s}");
    assert!((s.peak_brace_force_kn - 1224.1 * s.peak_brace_disp_mm).abs() < 1e-6);
    assert_eq!(peak_abs(&r.story_disp_mm), s.peak_story_disp_mm);
}

#[test]
fn shipped_records_round_trip() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("data/ground_motions");
    // (file, embedded name, NPTS, DT, PGA) from data/ground_motions/README.md.
    let table = [
        ("IELC180.AT2", "el-centro", 4000, 0.01, 0.3129),
        (
            "RSN1044_NORTHR_NWH360.AT2",
            "northridge",
            2000,
            0.02,
            0.5904,
        ),
        (
            "RSN766_LOMAP_G02000.AT2",
            "loma-prieta",
            7998,
            0.005,
            0.3697,
        ),
        ("TAK000.AT2", "kobe", 4096, 0.01, 0.6177),
    ];
    for (file, name, npts, dt, pga) in table {
        let m = GroundMotion::from_path(&dir.join(file)).unwrap();
        assert_eq!(m.accel_g.len(), npts, "{file}");
        assert!((m.dt_s - dt).abs() < 1e-12, "{file}");
        assert!(
            (m.pga_g() - pga).abs() < 0.0005,
            "{file}: PGA {}",
            m.pga_g()
        );
        let e = GroundMotion::embedded(name).unwrap();
        assert_eq!(e.accel_g, m.accel_g, "{name}");
        assert_eq!(e.dt_s, m.dt_s);
        // Written back and read again, unchanged.
        let again = parse_at2(&m.to_at2(), &m.name).unwrap();
        assert_eq!(again, m);
    }
    let ec = GroundMotion::el_centro();
    assert!((ec.pga_g() - 0.313).abs() < 0.0005);
    assert!((ec.duration_s() - 39.99).abs() < 1e-9);
}

fn rths(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_rths"))
        .args(args)
        .output()
        .unwrap()
}

#[test]
fn analyze_binary_writes_csv_png_and_summary() {
    let dir = tempfile::tempdir().unwrap();
    let csv = dir.path().join("ec.csv");
    let png = dir.path().join("ec.png");
    let out = rths(&[
        "analyze",
        "--out",
        csv.to_str().unwrap(),
        "--plot",
        png.to_str().unwrap(),
    ]);
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{stdout}{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let drift_line = stdout
        .lines()
        .find(|l| l.starts_with("peak story drift"))
        .unwrap();
    let drift: f64 = drift_line
        .split_whitespace()
        .nth(3)
        .unwrap()
        .parse()
        .unwrap();
    assert!((drift - 17.76).abs() < 0.05, "{drift_line}");

    let text = std::fs::read_to_string(&csv).unwrap();
    let mut lines = text.lines();
    assert_eq!(lines.next(), Some(ANALYSIS_CSV_HEADER));
    assert_eq!(
        ANALYSIS_CSV_HEADER,
        "time_s,ground_accel_mm_s2,story_disp_mm,brace_disp_mm,brace_force_kn"
    );
    let rows: Vec<&str> = lines.collect();
    assert_eq!(rows.len(), 81_900);
    let last: Vec<f64> = rows[rows.len() - 1]
        .split(',')
        .map(|v| v.parse().unwrap())
        .collect();
    assert_eq!(last.len(), 5);
    assert!((last[0] - 81_899.0 / 2048.0).abs() < 1e-12);
    let png_bytes = std::fs::read(&png).unwrap();
    assert!(png_bytes.starts_with(b"\x89PNG"));
    assert!(png_bytes.len() > 10_000);
}

#[test]
fn analyze_binary_methods_and_names() {
    let out = rths(&[
        "analyze", "--motion", "kobe", "--method", "cr", "--scale", "0.5",
    ]);
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success());
    assert!(stdout.contains("kobe ×0.5"), "{stdout}");
    assert!(stdout.contains("CR explicit"), "{stdout}");
}

#[test]
fn analyze_binary_reports_bad_file_with_line_number() {
    let dir = tempfile::tempdir().unwrap();
    let bad = dir.path().join("bad.at2");
    std::fs::write(
        &bad,
        "A\r\nB\r\nC\r\nNPTS= 3, DT= .01 SEC\r\n 0.1 0.2\r\n 0.3x\r\n",
    )
    .unwrap();
    let out = rths(&["analyze", "--motion", bad.to_str().unwrap()]);
    assert!(!out.status.success());
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(stderr.contains("line 6"), "{stderr}");
    assert!(stderr.contains("`0.3x` is not a number"), "{stderr}");

    let nodt = dir.path().join("nodt.AT2");
    std::fs::write(&nodt, "A\nB\nC\nNPTS= 3\n 0.1 0.2 0.3\n").unwrap();
    let out = rths(&["analyze", "--motion", nodt.to_str().unwrap()]);
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("line 4: no `DT=`"));

    let out = rths(&["analyze", "--motion", "no-such-record"]);
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("el-centro"));
}

#[test]
fn analyze_warns_when_a_record_exceeds_the_actuator() {
    // Northridge drives the brace to 35.7 mm, beyond the ±25.4 mm stroke; El Centro does not.
    let out = rths(&["analyze", "--motion", "northridge"]);
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success());
    assert!(stdout.contains("note: peak brace deformation"), "{stdout}");
    assert!(stdout.contains("--scale <= 0.71"), "{stdout}");
    let out = rths(&["analyze"]);
    assert!(!String::from_utf8_lossy(&out.stdout).contains("note:"));
}

/// One reference response: the analysis (Chang), the trainer's target and a per-tick
/// `rths_core::reference::Reference` (what the firmware harness steps) agree bit for bit, on the
/// record as `rths_core::motion::Record` interpolates it tick by tick.
#[test]
fn one_reference_response_for_analysis_trainer_and_firmware() {
    use rths_core::motion::Record;
    use rths_core::reference::Reference;
    let motion = GroundMotion::try_el_centro().unwrap();
    let ag = motion.resample_mm_s2(DT_S);
    let record = Record::new(&motion.accel_g, motion.dt_s);
    assert_eq!(record.ticks(DT_S), ag.len());
    for (k, a) in ag.iter().enumerate() {
        assert_eq!(
            a.to_bits(),
            record.accel_mm_s2(k, DT_S).to_bits(),
            "tick {k}"
        );
    }
    let p = Prototype::paper();
    let analysis = pure_response(&p, &ag, DT_S, Method::Chang).unwrap();
    let trainer = rths::machinery::train::data::pure_response(&p, &ag, DT_S).unwrap();
    let mut reference = Reference::new(&p, DT_S, ag[0]).unwrap();
    let per_tick: Vec<f64> = std::iter::once(reference.brace_disp_mm())
        .chain(ag[1..].iter().map(|&a| reference.advance(a)))
        .collect();
    let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
    assert_eq!(bits(&analysis.brace_disp_mm), bits(&per_tick));
    assert_eq!(bits(&trainer.brace_disp_mm), bits(&per_tick));
}

/// `rths analyze --structure --free-s`: the run's history is the record and that much free
/// vibration (so a held-out run can come to rest), and a free vibration that is not a number of
/// seconds between 0 and 600 is refused.
#[test]
fn analyze_free_vibration_lengthens_the_history_and_refuses_a_bad_one() {
    let dir = tempfile::tempdir().unwrap();
    let structure =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("data/structures/shear3-yielding.json");
    let rows = |free: &str| {
        let h = dir.path().join(format!("h{free}.csv"));
        let out = rths(&[
            "analyze",
            "--structure",
            structure.to_str().unwrap(),
            "--motion",
            "el-centro",
            "--free-s",
            free,
            "--history",
            h.to_str().unwrap(),
        ]);
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        assert!(
            String::from_utf8_lossy(&out.stdout).contains(&format!("+{free} s free vibration")),
            "{}",
            String::from_utf8_lossy(&out.stdout)
        );
        std::fs::read_to_string(&h).unwrap().lines().count() - 1
    };
    let (short, long) = (rows("10"), rows("30"));
    assert_eq!(long - short, 20 * 2048);
    for bad in ["-1", "NaN", "1e9"] {
        let out = rths(&[
            "analyze",
            "--structure",
            structure.to_str().unwrap(),
            &format!("--free-s={bad}"),
        ]);
        assert!(!out.status.success(), "--free-s {bad}");
        assert!(
            String::from_utf8_lossy(&out.stderr).contains("--free-s"),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
    }
}
