//! Benchmark (asserts nothing; `cargo xtask experiment batch_bench [N …]`): a production
//! batch's speed and memory. For each batch size N (default 10 and 100): the simulator's
//! chamber run of N units (8 550 one-second rows each, the size of the real chamber log),
//! split into units and calibrated by `qfa_batch::run` at 1 worker thread (N ≤ 10
//! only: it takes N × the single-core cost) and at 2, each run into a fresh folder. Prints
//! one `key=value` line per run:
//! `units threads seconds units_per_min cpu_s_per_unit seconds_per_unit vmhwm_mb`, where
//! `vmhwm_mb` is the process's peak resident memory so far (`VmHWM`), and a last line with
//! the memory each further unit adds, from the two largest batches. The chamber log is
//! written by a child process (this program with `write N DIR`) and read as `qfa-lab batch
//! --log` reads it, streamed (`from_chamber_file`), so the memory is the batch's alone.

use std::path::PathBuf;
use std::time::Instant;

use qfa_batch::input::from_chamber_file;
use qfa_batch::BatchOptions;
use qfa_log::open::ReadFlags;
use qfa_log::static_log::columns::{AccelUnit, TimeUnit};
use qfa_log::units::TempUnit;
use qfa_sim::population::{draw, write_chamber, PopulationSpec};

/// Peak resident memory of this process, MB (Linux `VmHWM`; 0 where it cannot be read).
fn vmhwm_mb() -> f64 {
    std::fs::read_to_string("/proc/self/status")
        .ok()
        .and_then(|s| s.lines().find(|l| l.starts_with("VmHWM:")).map(str::to_string))
        .and_then(|l| l.split_whitespace().nth(1).and_then(|k| k.parse::<f64>().ok()))
        .map_or(0.0, |kb| kb / 1024.0)
}

/// CPU time of this process so far, s (user + system, from `/proc/self/stat`).
fn cpu_s() -> f64 {
    let ticks = 100.0; // USER_HZ on Linux
    std::fs::read_to_string("/proc/self/stat")
        .ok()
        .and_then(|s| {
            let rest = s.rsplit_once(')')?.1;
            let f: Vec<&str> = rest.split_whitespace().collect();
            Some((f.get(11)?.parse::<f64>().ok()? + f.get(12)?.parse::<f64>().ok()?) / ticks)
        })
        .unwrap_or(0.0)
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    if let [_, cmd, n, dir] = args.as_slice() {
        if cmd == "write" {
            let n: usize = n.parse().expect("units");
            let truth = draw(&PopulationSpec { units: n, seed: 1, bad: true, truncated: 0, die_lags: false });
            write_chamber(std::path::Path::new(dir), &truth).expect("chamber log");
            return;
        }
    }
    let sizes: Vec<usize> = args.iter().skip(1).filter_map(|a| a.parse().ok()).collect();
    let sizes = if sizes.is_empty() { vec![10, 100] } else { sizes };
    let root = std::env::temp_dir().join(format!("qfa-batch-bench-{}", std::process::id()));
    let flags = ReadFlags {
        time_unit: Some(TimeUnit::S),
        accel_unit: Some(AccelUnit::G),
        temp_unit: Some(TempUnit::C),
        ..ReadFlags::default()
    };
    let mut peaks = Vec::new();
    for &n in &sizes {
        let dir: PathBuf = root.join(format!("n{n}"));
        std::fs::create_dir_all(&dir).expect("scratch folder");
        let exe = std::env::current_exe().expect("this program");
        let wrote = std::process::Command::new(exe).arg("write").arg(n.to_string()).arg(&dir).status();
        assert!(wrote.is_ok_and(|s| s.success()), "the chamber log of {n} units not written");
        let path = dir.join("chamber.tsv");
        let threads: &[usize] = if n <= 10 { &[1, 2] } else { &[2] };
        for &t in threads {
            let out = dir.join(format!("out{t}"));
            let (t0, c0) = (Instant::now(), cpu_s());
            let chamber = from_chamber_file(&path, &flags, &out).expect("split");
            qfa_batch::run(&chamber.units, &out, &BatchOptions { threads: t, ..BatchOptions::default() })
                .expect("batch");
            let (secs, cpu) = (t0.elapsed().as_secs_f64(), cpu_s() - c0);
            let peak = vmhwm_mb();
            println!(
                "units={n} threads={t} seconds={secs:.1} units_per_min={:.1} cpu_s_per_unit={:.2} seconds_per_unit={:.3} \
                 vmhwm_mb={peak:.0}",
                n as f64 * 60.0 / secs,
                cpu / n as f64,
                secs / n as f64
            );
            peaks.push((n, peak));
        }
        let _ = std::fs::remove_dir_all(&dir);
    }
    if let [.., (n0, m0), (n1, m1)] = peaks.as_slice() {
        if n1 > n0 {
            println!("mb_per_added_unit={:.3} (from {n0} to {n1} units)", (m1 - m0) / (*n1 - *n0) as f64);
        }
    }
    let _ = std::fs::remove_dir_all(&root);
}
