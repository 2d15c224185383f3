//! CPU time of prepare and compare on real teeth, measured as this
//! thread's CPU time (so that other processes on the machine do not
//! inflate it). Run with
//! `cargo test --release --test cp_timing -- --ignored --nocapture`.

mod cp_support;

use morphoid::cp::{self, CpParams};

/// This thread's user + system CPU time in seconds (Linux), if available.
fn thread_cpu_seconds() -> Option<f64> {
    let stat = std::fs::read_to_string("/proc/thread-self/stat").ok()?;
    let rest = &stat[stat.rfind(')')? + 2..];
    let f: Vec<&str> = rest.split_whitespace().collect();
    let ticks: f64 = f.get(11)?.parse::<f64>().ok()? + f.get(12)?.parse::<f64>().ok()?;
    Some(ticks / 100.0)
}

#[test]
#[ignore]
fn cpu_time_of_prepare_and_compare() {
    let Some(dir) = cp_support::data_dir() else {
        return;
    };
    let params: CpParams = match std::env::var("CP_PARAMS") {
        Ok(json) => serde_json::from_str(&json).expect("CP_PARAMS is CpParams JSON"),
        Err(_) => CpParams::default(),
    };
    let names = cp_support::tooth_names(&dir);
    let meshes: Vec<_> = names
        .iter()
        .step_by(10)
        .map(|n| cp_support::load_tooth(&dir, n))
        .collect();
    let (Some(c0), w0) = (thread_cpu_seconds(), std::time::Instant::now()) else {
        println!("skipped: no per-thread CPU clock");
        return;
    };
    let prepared: Vec<_> = meshes
        .iter()
        .map(|m| cp::prepare(m, &params.prepare).expect("prepare"))
        .collect();
    let c1 = thread_cpu_seconds().unwrap_or(c0);
    let w1 = w0.elapsed();
    let mut pairs = 0;
    for i in 0..prepared.len() {
        for j in i + 1..prepared.len() {
            std::hint::black_box(cp::compare(&prepared[i], &prepared[j], &params.compare).distance);
            pairs += 1;
        }
    }
    let c2 = thread_cpu_seconds().unwrap_or(c1);
    let w2 = w0.elapsed() - w1;
    println!(
        "prepare: {:.1} ms CPU ({:.1} ms wall) per tooth; compare: {:.1} ms CPU ({:.1} ms wall) per pair ({} pairs)",
        1e3 * (c1 - c0) / prepared.len() as f64,
        w1.as_secs_f64() * 1e3 / prepared.len() as f64,
        1e3 * (c2 - c1) / pairs as f64,
        w2.as_secs_f64() * 1e3 / pairs as f64,
        pairs
    );
}
