//! The long mutation run: `IPFN_MUTATIONS` inputs per format (default 10000) derived from valid
//! files, each through the loader the CLI uses, with the allocation cap and hang watchdog of
//! `tests/mutate`. Prints one row per format and fails on any problem.
//!
//! `cargo bench --bench mutate`; `IPFN_MUTATION_SEED` changes the inputs.

#[path = "../tests/mutate/mod.rs"]
mod mutate;

#[global_allocator]
static ALLOC: mutate::CappedAlloc = mutate::CappedAlloc;

fn main() {
    let count: usize = std::env::var("IPFN_MUTATIONS")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(10000);
    let seed: u64 = std::env::var("IPFN_MUTATION_SEED")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(7);
    let dir = tempfile::tempdir().unwrap();
    let formats = mutate::formats::formats(dir.path());
    std::panic::set_hook(Box::new(|_| {}));
    println!(
        "| format | inputs | loaded | refused (one line, naming the file) | problems | peak live memory |"
    );
    println!("|---|---|---|---|---|---|");
    let mut problems = Vec::new();
    for (i, format) in formats.iter().enumerate() {
        let start = std::time::Instant::now();
        let tally = mutate::run(format, count, seed * 1000 + i as u64, dir.path());
        println!(
            "| {} | {} | {} | {} | {} | {} KiB |",
            format.name,
            tally.tried,
            tally.accepted,
            tally.refused,
            tally.problems.len(),
            tally.peak_bytes >> 10
        );
        eprintln!("{}: {:.1} s", format.name, start.elapsed().as_secs_f64());
        problems.extend(tally.problems);
    }
    let _ = std::panic::take_hook();
    for p in &problems {
        println!("problem: {p}");
    }
    assert!(problems.is_empty(), "{} problems", problems.len());
}
