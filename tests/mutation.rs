//! Every input format, mutation-tested (a fixed-seed subset; `cargo bench --bench mutate` runs
//! the long version): no panic, no allocation beyond the cap, no hang, and every refusal one
//! line naming the file. One test, so the allocation count sees one input at a time.

mod mutate;

use mutate::CappedAlloc;
use mutate::formats::formats;

#[global_allocator]
static ALLOC: CappedAlloc = CappedAlloc;

/// Mutations per format in the test (the bench runs thousands).
const PER_FORMAT: usize = 300;

#[test]
fn every_format_survives_mutated_inputs() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let formats = formats(d);
    std::panic::set_hook(Box::new(|_| {}));
    let mut problems = Vec::new();
    for (i, format) in formats.iter().enumerate() {
        // The valid file itself loads.
        std::fs::write(d.join(format.file_name), &format.valid).unwrap();
        if let Err(e) = (format.load)(&d.join(format.file_name)) {
            problems.push(format!("{}: the valid file is refused: {e}", format.name));
        }
        let tally = mutate::run(format, PER_FORMAT, 1000 + i as u64, d);
        eprintln!(
            "{}: {} tried, {} loaded, {} refused, peak {} KiB",
            format.name,
            tally.tried,
            tally.accepted,
            tally.refused,
            tally.peak_bytes >> 10
        );
        if tally.refused == 0 {
            problems.push(format!("{}: no mutation was refused", format.name));
        }
        problems.extend(tally.problems);
    }
    let _ = std::panic::take_hook();
    assert!(
        problems.is_empty(),
        "{} problems:\n{}",
        problems.len(),
        problems.join("\n")
    );
}
