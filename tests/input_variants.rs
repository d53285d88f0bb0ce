//! The input count (issue 27): malformed variants of one valid file of every kind a user hands
//! `rths`, each loaded the way the command that takes it loads it (the reader, then the checks
//! the controller's path makes). Every variant must give a value or an error, never a panic; the
//! variants no file may hold (empty, truncated, binary garbage, a number out of range or of the
//! wrong type, another controller rate) must be refused with a message. The test prints the count
//! per file kind and variant class and what each got (docs/reliability.md "Input count").
//!
//! Variants of a JSON file: empty; cut at 16 points; 4 garbage byte strings; every numeric leaf
//! replaced in turn by `1e999` (out of range), `"x"` (wrong type), `null`, `1e300`, `-1e300`, `0`
//! and `-1`; the `dt_s` fields doubled (another rate). Of a text file (AT2, CSV, recordings):
//! empty; cut at 16 points; 4 garbage strings; every numeric token replaced in turn by `NaN`,
//! `inf`, `x`, `1e300` and `-1e300`.

use std::collections::BTreeMap;
use std::path::Path;

use rths_core::params::DT_S;
use serde_json::Value;

/// The outcome of one variant.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Got {
    Accepted,
    Refused,
}

/// Which variants must be refused.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
enum Class {
    Empty,
    Truncated,
    Garbage,
    OutOfRange,
    WrongType,
    Null,
    Huge,
    ZeroOrNegative,
    OtherRate,
    NonFinite,
}

impl Class {
    fn must_refuse(self) -> bool {
        matches!(
            self,
            Class::Empty
                | Class::Garbage
                | Class::OutOfRange
                | Class::WrongType
                | Class::OtherRate
                | Class::NonFinite
        )
    }
    fn name(self) -> &'static str {
        match self {
            Class::Empty => "empty",
            Class::Truncated => "truncated",
            Class::Garbage => "binary garbage",
            Class::OutOfRange => "number out of range (1e999)",
            Class::WrongType => "wrong type (\"x\")",
            Class::Null => "null",
            Class::Huge => "huge (±1e300)",
            Class::ZeroOrNegative => "0 or -1",
            Class::OtherRate => "another rate (dt_s × 2)",
            Class::NonFinite => "NaN or inf",
        }
    }
}

/// A loader: `Ok(())` if the command would take the text, else the error message.
type Loader = fn(&str) -> Result<(), String>;

fn e(x: impl std::fmt::Display) -> String {
    x.to_string()
}

fn model(text: &str) -> Result<(), String> {
    use rths::machinery::model_file::{ModelFile, ModelKind};
    let m = ModelFile::from_json(text).map_err(e)?;
    rths::machinery::models::check_for_controller(&m).map_err(e)?;
    match m.kind {
        ModelKind::Lr => rths::machinery::models::lr_params(&m)
            .map(|_| ())
            .map_err(e),
        ModelKind::Rnn => rths::machinery::models::rnn_params(&m)
            .map(|_| ())
            .map_err(e),
        ModelKind::Lrx => rths::machinery::models::lrx_params(&m)
            .map(|_| ())
            .map_err(e),
    }
}

fn nl_model(text: &str) -> Result<(), String> {
    let m = rths_files::nl_model_file::NlModelFile::from_json(text).map_err(e)?;
    rths::machinery::structure::model::check_rate(&m).map_err(e)?;
    m.params(DT_S).map(|_| ()).map_err(e)
}

fn meta_model(text: &str) -> Result<(), String> {
    let s = rths_files::structure_file::Structure::from_json(META_STRUCTURE).map_err(e)?;
    let m = rths_files::structure_meta::MetaFile::from_json(text).map_err(e)?;
    m.check(&s, DT_S).map(|_| ()).map_err(e)
}

fn reduced_model(text: &str) -> Result<(), String> {
    let s =
        rths::machinery::imported::ImportedStructure::from_json(REDUCED_STRUCTURE).map_err(e)?;
    let f = rths::machinery::imported::reduced::ReducedModelFile::from_json(text).map_err(e)?;
    let a = f.arrays_for(&s, DT_S).map_err(e)?;
    a.spec().params(DT_S).map(|_| ()).map_err(e)
}

fn rig(text: &str) -> Result<(), String> {
    let r = rths::machinery::identify::RigFile::from_json(text).map_err(e)?;
    rths::machinery::structure::rig::from_rig_file_named("paper-frame", &r, "rig").map_err(e)?;
    for kind in [rths_link::ModelKind::FeAts, rths_link::ModelKind::Lrx] {
        rths::link_host::wire::rig_values(&r, kind, 0.0).map_err(e)?;
    }
    Ok(())
}

fn structure(text: &str) -> Result<(), String> {
    let s = rths_files::structure_file::Structure::from_json(text).map_err(e)?;
    s.numerical().map_err(e)?;
    s.whole().map_err(e)?;
    if s.story_laws().is_some() {
        s.nonlinear_numerical(DT_S).map_err(e)?;
    }
    Ok(())
}

fn imported(text: &str) -> Result<(), String> {
    rths::machinery::imported::ImportedStructure::from_json(text)
        .map(|_| ())
        .map_err(e)
}

fn at2(text: &str) -> Result<(), String> {
    let m = rths::machinery::motion::parse_at2(text, "v.AT2").map_err(e)?;
    m.validate().map_err(e)
}

fn motion_csv(text: &str) -> Result<(), String> {
    let m = rths::machinery::motion::parse_csv(text, "v.csv").map_err(e)?;
    m.validate().map_err(e)
}

fn history(text: &str) -> Result<(), String> {
    rths_files::history::parse_csv(text, Path::new("v.csv"), DT_S)
        .map(|_| ())
        .map_err(e)
}

/// As `rths report` reads one: the header's numbers and the clean-run rule (the reference needs
/// the record the header names, which a variant does not change).
fn recording(text: &str) -> Result<(), String> {
    let r = rths::link_host::read_recording(text).map_err(e)?;
    match rths::link_host::first_unclean_sample(&r.rows) {
        Some(u) => Err(format!("{} is {} at tick {}", u.channel, u.value, u.tick)),
        None => Ok(()),
    }
}

const META_STRUCTURE: &str = include_str!("../data/structures/shear3-yielding.json");
const REDUCED_STRUCTURE: &str = include_str!("../data/structures/opensees-frame-1x1.json");

/// The file kinds: name, a valid file (a shipped one, or one `rths` wrote), its loader, JSON or not.
fn kinds() -> Vec<(&'static str, &'static str, Loader, bool)> {
    vec![
        (
            "model lr",
            include_str!("../data/models/lr.json"),
            model,
            true,
        ),
        (
            "model rnn",
            include_str!("../data/models/rnn-5.json"),
            model,
            true,
        ),
        (
            "model lrx",
            include_str!("../data/models/lrx.json"),
            model,
            true,
        ),
        (
            "model nonlinear (nl-*)",
            include_str!("../data/models/nl-paper-frame-yielding.json"),
            nl_model,
            true,
        ),
        (
            "model structure-meta",
            include_str!("../fuzz/seeds/meta_model_file/shear3-yielding-meta.json"),
            meta_model,
            true,
        ),
        (
            "model reduced (imported)",
            include_str!("../fuzz/seeds/meta_model_file/frame-1x1-reduced.json"),
            reduced_model,
            true,
        ),
        (
            "rig file",
            include_str!("../fuzz/seeds/rig_file/rig.json"),
            rig,
            true,
        ),
        (
            "structure (dense)",
            include_str!("../data/structures/shear3-yielding.json"),
            structure,
            true,
        ),
        (
            "structure (imported OpenSees)",
            REDUCED_STRUCTURE,
            imported,
            true,
        ),
        (
            "ground motion AT2",
            include_str!("../fuzz/seeds/at2/small.at2"),
            at2,
            false,
        ),
        (
            "ground motion CSV",
            include_str!("../fuzz/seeds/csv/small.csv"),
            motion_csv,
            false,
        ),
        (
            "time history CSV",
            include_str!("../fuzz/seeds/history/good.csv"),
            history,
            false,
        ),
        (
            "recording",
            include_str!("../fuzz/seeds/recording/small.csv"),
            recording,
            false,
        ),
    ]
}

const GARBAGE: [&[u8]; 4] = [
    b"\x00\x01\x02\xff\xfe",
    b"\x89PNG\r\n\x1a\n\x00\x00",
    b"{\"format\":\xff\xff}",
    b"\xde\xad\xbe\xef\xde\xad\xbe\xef\x00",
];

fn common(text: &str) -> Vec<(Class, String)> {
    let mut v = vec![(Class::Empty, String::new())];
    let n = text.len();
    for k in 1..=16 {
        let mut cut = n * k / 17;
        while !text.is_char_boundary(cut) {
            cut -= 1;
        }
        v.push((Class::Truncated, text[..cut].to_string()));
    }
    for g in GARBAGE {
        v.push((Class::Garbage, String::from_utf8_lossy(g).into_owned()));
    }
    v
}

/// Every numeric leaf's path in `v`.
fn leaves(v: &Value, path: &mut Vec<Value>, out: &mut Vec<Vec<Value>>) {
    match v {
        Value::Number(_) => out.push(path.clone()),
        Value::Array(a) => {
            for (i, x) in a.iter().enumerate() {
                path.push(Value::from(i));
                leaves(x, path, out);
                path.pop();
            }
        }
        Value::Object(o) => {
            for (k, x) in o {
                path.push(Value::from(k.as_str()));
                leaves(x, path, out);
                path.pop();
            }
        }
        _ => {}
    }
}

fn at<'a>(v: &'a mut Value, path: &[Value]) -> Option<&'a mut Value> {
    let mut cur = v;
    for p in path {
        cur = match p {
            Value::String(k) => cur.get_mut(k.as_str())?,
            Value::Number(i) => cur.get_mut(usize::try_from(i.as_u64()?).ok()?)?,
            _ => return None,
        };
    }
    Some(cur)
}

fn json_variants(text: &str) -> Vec<(Class, String)> {
    let mut out = common(text);
    let doc: Value = serde_json::from_str(text).unwrap();
    let mut paths = Vec::new();
    leaves(&doc, &mut Vec::new(), &mut paths);
    const MARK: &str = "\"__VARIANT__\"";
    for p in &paths {
        let mut d = doc.clone();
        let slot = at(&mut d, p).unwrap();
        *slot = Value::from("__VARIANT__");
        let t = serde_json::to_string(&d).unwrap();
        for (class, value) in [
            (Class::OutOfRange, "1e999"),
            (Class::WrongType, "\"x\""),
            (Class::Null, "null"),
            (Class::Huge, "1e300"),
            (Class::Huge, "-1e300"),
            (Class::ZeroOrNegative, "0"),
            (Class::ZeroOrNegative, "-1"),
        ] {
            out.push((class, t.replacen(MARK, value, 1)));
        }
        // Every file with a `dt_s` is made at a controller rate (the rate rule): twice it is refused.
        if p.last() == Some(&Value::from("dt_s")) {
            let dt = at(&mut doc.clone(), p).and_then(|x| x.as_f64()).unwrap();
            out.push((
                Class::OtherRate,
                t.replacen(MARK, &format!("{}", 2.0 * dt), 1),
            ));
        }
    }
    out
}

/// The byte ranges of the numeric tokens of a text file.
fn numbers(text: &str) -> Vec<(usize, usize)> {
    let b = text.as_bytes();
    let mut out = Vec::new();
    let mut i = 0;
    while i < b.len() {
        let starts = b[i].is_ascii_digit()
            || (matches!(b[i], b'-' | b'.') && b.get(i + 1).is_some_and(|c| c.is_ascii_digit()));
        // A number glued to a word (`a3974f36`, `×0.5` in a display name) is part of the word.
        let word_before = i > 0
            && (b[i - 1].is_ascii_alphanumeric()
                || matches!(b[i - 1], b'_' | b'.')
                || b[i - 1] >= 0x80);
        if starts && !word_before {
            let s = i;
            i += 1;
            while i < b.len()
                && (b[i].is_ascii_digit()
                    || matches!(b[i], b'.' | b'e' | b'E' | b'D' | b'-' | b'+'))
            {
                i += 1;
            }
            out.push((s, i));
        } else {
            i += 1;
        }
    }
    out
}

fn text_variants(text: &str) -> Vec<(Class, String)> {
    let mut out = common(text);
    for (s, t) in numbers(text) {
        for (class, value) in [
            (Class::NonFinite, "NaN"),
            (Class::NonFinite, "inf"),
            (Class::WrongType, "x"),
            (Class::Huge, "1e300"),
            (Class::Huge, "-1e300"),
        ] {
            out.push((class, format!("{}{value}{}", &text[..s], &text[t..])));
        }
    }
    out
}

#[test]
fn every_malformed_variant_of_every_file_kind_is_refused_or_valid_never_a_panic() {
    let mut report = String::new();
    let mut failures = Vec::new();
    let mut total = 0;
    for (kind, seed, load, json) in kinds() {
        assert_eq!(load(seed), Ok(()), "{kind}: the valid file is refused");
        let variants = if json {
            json_variants(seed)
        } else {
            text_variants(seed)
        };
        let mut tally: BTreeMap<Class, [usize; 2]> = BTreeMap::new();
        for (class, text) in &variants {
            let got = match std::panic::catch_unwind(|| load(text)) {
                Err(_) => {
                    failures.push(format!("{kind}: PANIC on a {} variant", class.name()));
                    continue;
                }
                Ok(Ok(())) => Got::Accepted,
                Ok(Err(msg)) => {
                    if msg.trim().is_empty() {
                        failures.push(format!("{kind}: empty error on a {} variant", class.name()));
                    }
                    Got::Refused
                }
            };
            if got == Got::Accepted && class.must_refuse() {
                failures.push(format!("{kind}: a {} variant was accepted", class.name()));
                eprintln!("accepted {kind} {} variant:\n{text}\n", class.name());
            }
            let t = tally.entry(*class).or_default();
            t[usize::from(got == Got::Refused)] += 1;
        }
        total += variants.len();
        let classes: Vec<String> = tally
            .iter()
            .map(|(c, [acc, refd])| {
                format!(
                    "{} {}: {refd} refused, {acc} accepted",
                    acc + refd,
                    c.name()
                )
            })
            .collect();
        report.push_str(&format!(
            "| {kind} | {} | {} |\n",
            variants.len(),
            classes.join("; ")
        ));
    }
    println!("| file kind | variants | by class |\n|---|---|---|\n{report}total: {total} variants");
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}
