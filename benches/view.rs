//! `cargo bench --bench view`: `ipfn view` under load, on loopback, beside `ipfn synth` painting
//! the same pixels in the same run.
//!
//! 32 clients ask at once for 128 distinct 256-pixel tiles of the shipped honeycomb (cold, then
//! again from the cache), while a prober asks for the page's `/api/info` every 20 ms. The table
//! gives tile throughput against synth's (one 2048x4096 image: the same 8 Mpx), and the page's
//! latency under load against idle.

use std::io::{BufRead, BufReader};
use std::process::{Command, Stdio};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

const CLIENTS: usize = 32;
const TILES: usize = 128;
const SIDE: usize = 256;

fn agent() -> ureq::Agent {
    ureq::Agent::config_builder()
        .http_status_as_error(false)
        .timeout_global(Some(Duration::from_secs(300)))
        .build()
        .into()
}

/// Status and seconds of one GET.
fn get(agent: &ureq::Agent, url: &str) -> (u16, f64) {
    let start = Instant::now();
    let mut response = agent.get(url).call().expect("the server answers");
    let _ = response
        .body_mut()
        .with_config()
        .limit(1 << 28)
        .read_to_vec();
    (response.status().as_u16(), start.elapsed().as_secs_f64())
}

fn percentile(values: &mut [f64], p: f64) -> f64 {
    values.sort_by(f64::total_cmp);
    values[((values.len() - 1) as f64 * p).round() as usize]
}

/// All tiles by `CLIENTS` clients at once (each retries a 503 after 100 ms): wall seconds, the
/// latencies of answered tiles, 503s seen; and `/api/info` latencies meanwhile.
fn storm(base: &str) -> (f64, Vec<f64>, usize, Vec<f64>) {
    let done = Arc::new(AtomicBool::new(false));
    let prober = {
        let (base, done) = (base.to_string(), done.clone());
        std::thread::spawn(move || {
            let agent = agent();
            let mut latencies = Vec::new();
            while !done.load(Ordering::SeqCst) {
                latencies.push(get(&agent, &format!("{base}/api/info")).1);
                std::thread::sleep(Duration::from_millis(20));
            }
            latencies
        })
    };
    let start = Instant::now();
    let clients: Vec<_> = (0..CLIENTS)
        .map(|c| {
            let base = base.to_string();
            std::thread::spawn(move || {
                let agent = agent();
                let (mut latencies, mut busy) = (Vec::new(), 0);
                for t in (c..TILES).step_by(CLIENTS) {
                    let (x, y) = ((t % 16) * SIDE, (t / 16) * SIDE);
                    let url = format!("{base}/tile?size={SIDE}&x={x}&y={y}");
                    loop {
                        let (status, seconds) = get(&agent, &url);
                        if status == 200 {
                            latencies.push(seconds);
                            break;
                        }
                        assert_eq!(status, 503, "{url}");
                        busy += 1;
                        std::thread::sleep(Duration::from_millis(100));
                    }
                }
                (latencies, busy)
            })
        })
        .collect();
    let (mut latencies, mut busy) = (Vec::new(), 0);
    for client in clients {
        let (l, b) = client.join().unwrap();
        latencies.extend(l);
        busy += b;
    }
    let wall = start.elapsed().as_secs_f64();
    done.store(true, Ordering::SeqCst);
    (wall, latencies, busy, prober.join().unwrap())
}

fn main() {
    let dir = tempfile::tempdir().unwrap();
    let bin = env!("CARGO_BIN_EXE_ipfn");
    let mut server = Command::new(bin)
        .args(["view", "--export-dir", "."])
        .current_dir(dir.path())
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let mut line = String::new();
    BufReader::new(server.stdout.take().unwrap())
        .read_line(&mut line)
        .unwrap();
    let base = line.trim().trim_end_matches('/').to_string();

    let agent = agent();
    let mut idle: Vec<f64> = (0..50)
        .map(|_| get(&agent, &format!("{base}/api/info")).1)
        .collect();
    let (cold_wall, mut cold, busy, mut loaded) = storm(&base);
    let (warm_wall, mut warm, _, _) = storm(&base);
    let _ = server.kill();
    let _ = server.wait();

    // The same 8 Mpx painted by `ipfn synth` as one image (both cores).
    let start = Instant::now();
    let out = Command::new(bin)
        .args([
            "synth", "-q", "--width", "4096", "--height", "2048", "--out", "same.png",
        ])
        .current_dir(dir.path())
        .output()
        .unwrap();
    assert!(out.status.success());
    let synth = start.elapsed().as_secs_f64();

    print_table(Figures {
        cold_wall,
        warm_wall,
        synth,
        busy,
        cold: &mut cold,
        warm: &mut warm,
        idle: &mut idle,
        loaded: &mut loaded,
    });
}

/// What one run measured.
struct Figures<'a> {
    cold_wall: f64,
    warm_wall: f64,
    synth: f64,
    busy: usize,
    cold: &'a mut [f64],
    warm: &'a mut [f64],
    idle: &'a mut [f64],
    loaded: &'a mut [f64],
}

fn print_table(f: Figures) {
    let Figures {
        cold_wall,
        warm_wall,
        synth,
        busy,
        cold,
        warm,
        idle,
        loaded,
    } = f;
    let mpx = (TILES * SIDE * SIDE) as f64 / 1e6;
    println!(
        "ipfn view under load: {CLIENTS} clients, {TILES} distinct {SIDE}px tiles (shipped honeycomb, {mpx:.1} Mpx), loopback"
    );
    println!("| figure | ours | reference (same run) | ratio |");
    println!("|---|---|---|---|");
    println!(
        "| cold tiles: Mpx/s (server) vs `ipfn synth` one {mpx:.1} Mpx image | {:.2} | {:.2} | {:.2} |",
        mpx / cold_wall,
        mpx / synth,
        synth / cold_wall
    );
    println!(
        "| cached tiles: Mpx/s vs cold | {:.1} | {:.2} | {:.0}x |",
        mpx / warm_wall,
        mpx / cold_wall,
        cold_wall / warm_wall
    );
    println!(
        "| tile latency p50 / p95, cold (s) | {:.2} / {:.2} | - | - |",
        percentile(cold, 0.5),
        percentile(cold, 0.95)
    );
    println!(
        "| tile latency p50 / p95, cached (ms) | {:.1} / {:.1} | - | - |",
        1e3 * percentile(warm, 0.5),
        1e3 * percentile(warm, 0.95)
    );
    let (idle50, idle95) = (percentile(idle, 0.5), percentile(idle, 0.95));
    let (load50, load95) = (percentile(loaded, 0.5), percentile(loaded, 0.95));
    println!(
        "| page (`/api/info`) p50 / p95 under load vs idle (ms) | {:.1} / {:.1} | {:.1} / {:.1} | {:.1} / {:.1} |",
        1e3 * load50,
        1e3 * load95,
        1e3 * idle50,
        1e3 * idle95,
        load50 / idle50,
        load95 / idle95
    );
    println!("| 503 (busy) answers, retried | {busy} | - | - |");
}
