//! Mutation testing of every input format: inputs derived from valid files (truncations at
//! every length class, bit flips, header fields set to 0, 1, -1 and huge values, text tokens
//! replaced by extreme numbers, NaN and infinity written over data) go through the loader the
//! CLI uses. None may panic, allocate beyond [`CAP_BYTES`] or hang; every failure must be one
//! line that names the file.
//!
//! Used by `tests/mutation.rs` (a fixed-seed subset) and `benches/mutate.rs` (a longer run).

#![allow(dead_code)]

use std::alloc::{GlobalAlloc, Layout, System};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::time::{Duration, Instant};

pub mod formats;

/// The most memory live at once while one input loads: 512 MiB.
pub const CAP_BYTES: usize = 512 << 20;

/// The system allocator, counting live bytes and refusing any single request over the cap (the
/// refusal aborts the process, which fails the run loudly).
pub struct CappedAlloc;

static LIVE: AtomicUsize = AtomicUsize::new(0);
static PEAK: AtomicUsize = AtomicUsize::new(0);

unsafe impl GlobalAlloc for CappedAlloc {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        if layout.size() > CAP_BYTES {
            return std::ptr::null_mut();
        }
        let live = LIVE.fetch_add(layout.size(), Ordering::Relaxed) + layout.size();
        PEAK.fetch_max(live, Ordering::Relaxed);
        unsafe { System.alloc(layout) }
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        LIVE.fetch_sub(layout.size(), Ordering::Relaxed);
        unsafe { System.dealloc(ptr, layout) }
    }
}

/// A small deterministic generator (SplitMix64), so a run is reproducible from its seed.
pub struct Rng(u64);

impl Rng {
    pub fn new(seed: u64) -> Self {
        Self(seed)
    }

    pub fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    pub fn below(&mut self, n: usize) -> usize {
        (self.next() % n.max(1) as u64) as usize
    }
}

/// Values written over header fields: 0, 1, -1, and huge ones, as 1, 2, 4 and 8 bytes.
const FIELD_VALUES: [u64; 6] = [0, 1, u64::MAX, 0x7FFF_FFFF, 0x8000_0000, 0xFFFF_FFF0];
/// Tokens written over numbers in text formats.
const TEXT_VALUES: [&str; 9] = [
    "0",
    "-1",
    "1e30",
    "nan",
    "inf",
    "-inf",
    "99999999999999999999",
    "1e-40",
    "18446744073709551616",
];

/// The `n`-th mutation of `valid` (`text`: the format is text, so tokens are mutated too), and
/// what it did.
pub fn mutate(valid: &[u8], text: bool, rng: &mut Rng) -> (Vec<u8>, String) {
    let mut bytes = valid.to_vec();
    let len = bytes.len();
    let kinds = if text { 6 } else { 5 };
    match rng.below(kinds) {
        0 => {
            // Truncation, at every length class: powers of two and their neighbours.
            let classes: Vec<usize> = (0..usize::BITS)
                .map(|b| 1usize << b)
                .take_while(|&p| p < len)
                .flat_map(|p| [p - 1, p, p + 1])
                .chain([0, len.saturating_sub(1), len / 2])
                .filter(|&n| n < len)
                .collect();
            let at = classes[rng.below(classes.len())];
            bytes.truncate(at);
            (bytes, format!("truncated to {at} bytes"))
        }
        1 => {
            let flips = 1 + rng.below(8);
            // Half the flips in the first 512 bytes, where the headers are.
            for _ in 0..flips {
                let window = if rng.below(2) == 0 { len.min(512) } else { len };
                let at = rng.below(window);
                bytes[at] ^= 1 << rng.below(8);
            }
            (bytes, format!("{flips} bits flipped"))
        }
        2 => {
            let width = [1, 2, 4, 8][rng.below(4)];
            let value = FIELD_VALUES[rng.below(FIELD_VALUES.len())];
            let at = rng.below(len.min(512).saturating_sub(width).max(1));
            let big = rng.below(2) == 0;
            let field: Vec<u8> = if big {
                value.to_be_bytes()[8 - width..].to_vec()
            } else {
                value.to_le_bytes()[..width].to_vec()
            };
            for (i, b) in field.iter().enumerate() {
                if at + i < len {
                    bytes[at + i] = *b;
                }
            }
            (
                bytes,
                format!("{width}-byte field at {at} set to {value:#x}"),
            )
        }
        3 => {
            // NaN or infinity over 4-byte aligned data words past the first 128 bytes.
            let value = [f32::NAN, f32::INFINITY, f32::NEG_INFINITY, f32::MAX][rng.below(4)];
            let words = (len.saturating_sub(128)) / 4;
            let count = 1 + rng.below(16);
            for _ in 0..count.min(words) {
                let at = 128 + 4 * rng.below(words);
                bytes[at..at + 4].copy_from_slice(&value.to_le_bytes());
            }
            (bytes, format!("{count} words set to {value}"))
        }
        4 => {
            // A run of bytes removed or repeated inside the file.
            let at = rng.below(len);
            let run = 1 + rng.below(64.min(len - at));
            if rng.below(2) == 0 {
                bytes.drain(at..at + run);
                (bytes, format!("{run} bytes removed at {at}"))
            } else {
                let copy = bytes[at..at + run].to_vec();
                bytes.splice(at..at, copy);
                (bytes, format!("{run} bytes repeated at {at}"))
            }
        }
        _ => {
            // Text: one number replaced by an extreme token.
            let s = String::from_utf8_lossy(valid).into_owned();
            let starts: Vec<usize> = s
                .char_indices()
                .filter(|(i, c)| {
                    c.is_ascii_digit() && (*i == 0 || !s.as_bytes()[i - 1].is_ascii_digit())
                })
                .map(|(i, _)| i)
                .collect();
            if starts.is_empty() {
                return (bytes, "unchanged".into());
            }
            let at = starts[rng.below(starts.len())];
            let end = s[at..]
                .find(|c: char| !(c.is_ascii_digit() || c == '.' || c == 'e' || c == '-'))
                .map_or(s.len(), |e| at + e);
            let token = TEXT_VALUES[rng.below(TEXT_VALUES.len())];
            let out = format!("{}{token}{}", &s[..at], &s[end..]);
            (out.into_bytes(), format!("number at {at} set to {token}"))
        }
    }
}

/// One format: its name, a valid file, whether it is text, and the loader the CLI uses.
pub struct Format {
    pub name: &'static str,
    pub file_name: &'static str,
    pub valid: Vec<u8>,
    pub text: bool,
    pub load: fn(&Path) -> ipfn::Result<()>,
}

/// What a run found for one format.
#[derive(Debug, Default)]
pub struct Tally {
    pub tried: usize,
    pub accepted: usize,
    pub refused: usize,
    pub problems: Vec<String>,
    pub peak_bytes: usize,
}

/// A watchdog: aborts the process, naming the input, if one input takes longer than
/// `limit` (a hang, not a slow input: the limit is generous).
struct Watchdog {
    busy: std::sync::Arc<(AtomicBool, std::sync::Mutex<(Instant, String)>)>,
}

impl Watchdog {
    fn start(limit: Duration) -> Self {
        let busy = std::sync::Arc::new((
            AtomicBool::new(false),
            std::sync::Mutex::new((Instant::now(), String::new())),
        ));
        let watch = busy.clone();
        std::thread::spawn(move || {
            loop {
                std::thread::sleep(Duration::from_millis(200));
                let (on, what) = &*watch;
                if on.load(Ordering::SeqCst) {
                    let what = what.lock().unwrap();
                    if what.0.elapsed() > limit {
                        eprintln!("HANG: {} ran for over {limit:?}", what.1);
                        std::process::abort();
                    }
                }
            }
        });
        Self { busy }
    }

    fn begin(&self, what: String) {
        *self.busy.1.lock().unwrap() = (Instant::now(), what);
        self.busy.0.store(true, Ordering::SeqCst);
    }

    fn end(&self) {
        self.busy.0.store(false, Ordering::SeqCst);
    }
}

/// Feeds `count` mutations of `format`'s valid file (seeded by `seed`) through its loader in
/// `dir`.
pub fn run(format: &Format, count: usize, seed: u64, dir: &Path) -> Tally {
    static WATCHDOG: std::sync::OnceLock<Watchdog> = std::sync::OnceLock::new();
    let watchdog = WATCHDOG.get_or_init(|| Watchdog::start(Duration::from_secs(60)));
    let mut rng = Rng::new(seed);
    let mut tally = Tally::default();
    let path: PathBuf = dir.join(format.file_name);
    let name = format.file_name;
    for i in 0..count {
        let (bytes, what) = mutate(&format.valid, format.text, &mut rng);
        std::fs::write(&path, &bytes).unwrap();
        let label = format!("{} #{i} ({what})", format.name);
        let base = LIVE.load(Ordering::Relaxed);
        PEAK.store(base, Ordering::Relaxed);
        watchdog.begin(label.clone());
        let result = std::panic::catch_unwind(|| (format.load)(&path));
        watchdog.end();
        let peak = PEAK.load(Ordering::Relaxed).saturating_sub(base);
        tally.peak_bytes = tally.peak_bytes.max(peak);
        tally.tried += 1;
        match result {
            Err(_) => tally.problems.push(format!("{label}: panicked")),
            Ok(Ok(())) => tally.accepted += 1,
            Ok(Err(e)) => {
                tally.refused += 1;
                let message = e.to_string();
                if message.contains('\n') || !message.contains(name) {
                    tally.problems.push(format!(
                        "{label}: error is not one line naming {name}: {message}"
                    ));
                }
            }
        }
        if peak > CAP_BYTES {
            tally
                .problems
                .push(format!("{label}: {peak} bytes live at once"));
        }
    }
    tally
}
