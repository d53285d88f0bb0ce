//! Every `--help` agrees with docs/commands.md: each flag of a synopsis there exists on its
//! command, a value written in place of a flag's argument is its default (when it has one), a list
//! `a|b|c` is its choices; no help shows rustdoc links; a group's description names each of its
//! subcommands; `simulate --scenario` names every scenario.

use std::path::Path;

use clap::CommandFactory;
use rths::cmd::cli::Cli;

fn docs() -> String {
    let p = Path::new(env!("CARGO_MANIFEST_DIR")).join("docs/commands.md");
    std::fs::read_to_string(p).unwrap()
}

/// The synopsis lines of the code blocks: each `rths ...` line with its continuation lines.
fn synopses(text: &str) -> Vec<String> {
    let mut out: Vec<String> = Vec::new();
    let mut in_block = false;
    for line in text.lines() {
        if line.starts_with("```") {
            in_block = !in_block;
            continue;
        }
        if !in_block {
            continue;
        }
        let t = line.trim_start();
        if t.starts_with("rths ") {
            out.push(t.to_string());
        } else if line.starts_with(' ') && t.starts_with(['[', '-', '(']) {
            if let Some(last) = out.last_mut() {
                last.push(' ');
                last.push_str(t);
            }
        }
    }
    out
}

/// The command a synopsis is of: the deepest subcommand its leading words name, and the chain.
fn command_of<'a>(root: &'a clap::Command, words: &[&str]) -> Vec<&'a clap::Command> {
    let mut chain = vec![root];
    for w in words {
        let names: Vec<&str> = w.split('|').collect();
        let last = *chain.last().unwrap();
        match last
            .get_subcommands()
            .find(|c| names.contains(&c.get_name()))
        {
            Some(c) => chain.push(c),
            None if w.starts_with(['[', '-', '(', '<']) => break,
            None => continue,
        }
    }
    chain
}

fn clean(token: &str) -> &str {
    token
        .trim_matches(|c| matches!(c, '[' | ']' | '(' | ')' | ','))
        .trim_end_matches("...")
        .trim_matches(|c| matches!(c, '[' | ']' | '(' | ')'))
}

#[test]
fn every_synopsis_flag_default_and_choice_is_the_programs() {
    let root = Cli::command();
    let text = docs();
    let mut checked = 0;
    let mut wrong = Vec::new();
    for syn in synopses(&text) {
        let words: Vec<&str> = syn.split_whitespace().skip(1).collect();
        let chain = command_of(&root, &words);
        if chain.len() == 1 {
            continue;
        }
        let names: Vec<&str> = chain.iter().skip(1).map(|c| c.get_name()).collect();
        for (i, w) in words.iter().enumerate() {
            let flag = clean(w);
            let Some(long) = flag.strip_prefix("--") else {
                continue;
            };
            let long = long.split('=').next().unwrap();
            let Some(arg) = chain
                .iter()
                .rev()
                .find_map(|c| c.get_arguments().find(|a| a.get_long() == Some(long)))
            else {
                wrong.push(format!("rths {}: no flag --{long}", names.join(" ")));
                continue;
            };
            checked += 1;
            let Some(value) = words.get(i + 1).map(|v| clean(v)) else {
                continue;
            };
            // A placeholder (N, PATH, RIG.json, ...), the next flag, a range, or none.
            let placeholder = value.is_empty()
                || value.starts_with('-')
                || value.contains("..")
                || value.chars().any(|c| c.is_ascii_uppercase());
            // `[--json]`: the flag's bracket closes before any value.
            if placeholder || w.ends_with([']', ')']) {
                continue;
            }
            let choices: Vec<String> = arg
                .get_possible_values()
                .iter()
                .filter(|p| !p.is_hide_set())
                .map(|p| p.get_name().to_string())
                .collect();
            let defaults: Vec<String> = arg
                .get_default_values()
                .iter()
                .map(|d| d.to_string_lossy().into_owned())
                .collect();
            let what = format!("rths {} --{long} {value}", names.join(" "));
            if value.contains('|') && !choices.is_empty() {
                let mut doc: Vec<&str> = value.split('|').collect();
                let mut want: Vec<&str> = choices.iter().map(String::as_str).collect();
                doc.sort_unstable();
                want.sort_unstable();
                if doc != want {
                    wrong.push(format!("{what}: the choices are {}", choices.join("|")));
                }
            } else if !defaults.is_empty() {
                let default = defaults.join(",");
                let same = match (value.parse::<f64>(), default.parse::<f64>()) {
                    (Ok(a), Ok(b)) => a == b,
                    _ => value == default,
                };
                if !same {
                    wrong.push(format!("{what}: the default is {default}"));
                }
            }
        }
    }
    assert!(
        wrong.is_empty(),
        "docs/commands.md disagrees with --help:\n{}",
        wrong.join("\n")
    );
    assert!(checked > 100, "only {checked} flags checked");
}

/// Every command's help, recursively.
fn all(c: &clap::Command, path: &str, out: &mut Vec<(String, clap::Command)>) {
    out.push((path.to_string(), c.clone()));
    for s in c.get_subcommands() {
        all(s, &format!("{path} {}", s.get_name()), out);
    }
}

#[test]
fn no_help_shows_rustdoc_links_and_each_group_names_its_subcommands() {
    let mut cmds = Vec::new();
    all(&Cli::command(), "rths", &mut cmds);
    for (path, mut c) in cmds {
        let help = c.render_long_help().to_string();
        assert!(
            !help.contains("[`"),
            "`{path} --help` shows a rustdoc link:\n{help}"
        );
        // A kind chosen by value (train's KIND) or by subcommand is named in the description.
        let about = c.get_about().map(|a| a.to_string()).unwrap_or_default();
        for kind in c
            .get_arguments()
            .filter(|a| a.is_positional())
            .flat_map(|a| a.get_possible_values())
        {
            assert!(
                about.to_lowercase().contains(kind.get_name()),
                "`{path}`'s description `{about}` does not name {}",
                kind.get_name()
            );
        }
    }
}

#[test]
fn simulate_help_names_every_scenario_and_rnn_epochs_are_the_trainings() {
    let root = Cli::command();
    let sim = root.find_subcommand("simulate").unwrap();
    let arg = sim
        .get_arguments()
        .find(|a| a.get_long() == Some("scenario"))
        .unwrap();
    let help = arg.get_help().unwrap().to_string();
    let names = rths::studies::scenario::ScenarioId::ALL
        .iter()
        .map(|s| s.to_string())
        .chain(
            rths::studies::nonlinear::scenario::STRUCTURE_SCENARIOS
                .iter()
                .map(|s| s.to_string()),
        );
    for name in names {
        assert!(
            help.contains(&name),
            "--scenario's help lacks {name}: {help}"
        );
    }
    let train = root.find_subcommand("train").unwrap();
    let epochs = train
        .get_arguments()
        .find(|a| a.get_long() == Some("epochs"))
        .unwrap();
    let help = epochs.get_help().unwrap().to_string();
    let want = format!(
        "Default {}",
        rths::machinery::train::rnn::ARX_FINE_TUNE_EPOCHS
    );
    assert!(help.contains(&want), "--epochs: `{want}` not in `{help}`");
    let training =
        std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("docs/training.md"))
            .unwrap();
    let want = format!(
        "`--epochs` {}",
        rths::machinery::train::rnn::ARX_FINE_TUNE_EPOCHS
    );
    assert!(training.contains(&want), "docs/training.md lacks `{want}`");
}
