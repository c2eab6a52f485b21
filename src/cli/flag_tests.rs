//! Every flag an error or hint of the library or the command line names is a flag `ipfn` has:
//! a message that tells a user to pass `--resize-maps` must not send them to a flag that does
//! not exist (or that only another program has).

use std::collections::BTreeSet;
use std::path::Path;

use clap::CommandFactory;

use super::Cli;

/// Flags of other programs that messages quote (`cargo install --path .`).
const OTHER_PROGRAMS: &[&str] = &["--path", "--features", "--locked", "--release"];

/// Every `--flag` inside a string literal of the Rust files under `dir`, with where it was.
fn quoted_flags(dir: &Path, found: &mut Vec<(String, String)>) {
    for entry in std::fs::read_dir(dir).unwrap() {
        let path = entry.unwrap().path();
        if path.is_dir() {
            quoted_flags(&path, found);
            continue;
        }
        if path.extension().is_none_or(|e| e != "rs") || path.ends_with("flag_tests.rs") {
            continue;
        }
        let text = std::fs::read_to_string(&path).unwrap();
        for (n, line) in text.lines().enumerate() {
            if line.trim_start().starts_with("//") {
                continue;
            }
            // The odd-numbered pieces between quotes are inside string literals.
            for literal in line.split('"').skip(1).step_by(2) {
                for (i, _) in literal.match_indices("--") {
                    let name: String = literal[i + 2..]
                        .chars()
                        .take_while(|c| c.is_ascii_lowercase() || c.is_ascii_digit() || *c == '-')
                        .collect();
                    if name.starts_with(|c: char| c.is_ascii_lowercase()) {
                        let at = format!("{}:{}", path.display(), n + 1);
                        found.push((format!("--{name}"), at));
                    }
                }
            }
        }
    }
}

#[test]
fn every_flag_a_message_names_is_a_flag_of_ipfn() {
    let cli = Cli::command();
    let known: BTreeSet<String> = cli
        .get_subcommands()
        .flat_map(|c| c.get_arguments())
        .filter_map(|a| a.get_long().map(|l| format!("--{l}")))
        .collect();
    let mut found = Vec::new();
    quoted_flags(
        &Path::new(env!("CARGO_MANIFEST_DIR")).join("src"),
        &mut found,
    );
    assert!(found.len() > 50, "the scan finds the messages' flags");
    let unknown: Vec<String> = found
        .iter()
        .filter(|(flag, _)| !known.contains(flag) && !OTHER_PROGRAMS.contains(&flag.as_str()))
        .map(|(flag, at)| format!("{flag} at {at}"))
        .collect();
    assert!(unknown.is_empty(), "flags no command has: {unknown:#?}");
}
