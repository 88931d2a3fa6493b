//! Outputs: `report.json`, `report.md`, `table.bin` (root-crate `Table`, 1 axis, rate
//! window 32, new slots on: what `qfa-lab compensate --table DIR/table.bin` loads, so
//! "discover, then compensate" is the workflow), the same bytes as `model.bin` (older
//! name), `model.toml`, `residuals.csv` and residual plots (PNG).
//!
//! The per-axis directories of a static log's discovery ([`super::static_axes`]) get no
//! `table.bin`/`model.bin`: their model is the named one in the axis's own units (K1 = 1,
//! `bias_drift` without a slot), and `compensate` takes a table of all the log's axes, the
//! one in the parent directory. Their `model.toml` is for reading and says so.

use std::fmt::Write as _;
use std::path::Path;

use anyhow::{Context, Result};
use plotters::prelude::*;
use qfa_thermal::table::{Input, Table, MAX_TABLE_BYTES};

use super::{Channels, Gaps, LogKind, Report};

fn gaps_text(g: &Gaps) -> String {
    match g {
        Gaps::Cycling { scale_factor_ppm, bias_ug } => {
            format!("scale factor {scale_factor_ppm:.2} ppm, bias {bias_ug:.2} µg")
        }
        Gaps::Single { value_rms } => format!("value {value_rms:.4}"),
    }
}

/// The root-crate table of the report's final model, for `input`: pulse counts for a
/// cycling log's scale-factor model, samples for a single-output log.
#[must_use]
pub fn table(report: &Report, input: Input) -> Option<Table> {
    // Not validated here: a single-channel log's model is in the log's own units (often
    // µg), which the root crate refuses as a table. `model.toml` is written either way;
    // `write` validates before `table.bin` and says why when it cannot.
    let mut t = Table {
        input,
        rate_window: crate::data::pairing::RATE_WINDOW as u16,
        axes: Default::default(),
        misalignment: None,
    };
    t.axes.push(report.model.clone()?).ok()?;
    Some(t)
}

/// Write every output into `dir`; `flashable` false leaves out `table.bin`/`model.bin`
/// (a static log's per-axis directory, see the module docs) and removes older ones there.
///
/// # Errors
/// A file could not be written.
pub fn write(ch: &Channels, report: &Report, dir: &Path, flashable: bool) -> Result<()> {
    std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    std::fs::write(dir.join("report.json"), serde_json::to_string_pretty(report)? + "\n")?;
    let mut notes = String::new();
    let input = match ch.kind {
        LogKind::Cycling => Input::PulseCounts,
        LogKind::Single => Input::Samples,
    };
    if !flashable {
        for f in ["table.bin", "model.bin"] {
            match std::fs::remove_file(dir.join(f)) {
                Err(e) if e.kind() != std::io::ErrorKind::NotFound => return Err(e.into()),
                _ => {}
            }
        }
    }
    if let Some(t) = table(report, input) {
        std::fs::write(dir.join("model.toml"), toml::to_string(&t)?)?;
    }
    if let Some(t) = table(report, input).filter(|_| flashable) {
        let mut buf = [0u8; MAX_TABLE_BYTES];
        match t.encode(&mut buf) {
            Ok(b) => {
                std::fs::write(dir.join("table.bin"), b)?;
                std::fs::write(dir.join("model.bin"), b)?;
            }
            Err(e) => {
                let _ = writeln!(notes, "\nThe table did not validate ({e:?}); no `table.bin` was written.");
            }
        }
    }
    write_csv(ch, report, &dir.join("residuals.csv"))?;
    if let Err(e) = plots(ch, report, dir) {
        let _ = writeln!(notes, "\nPlots failed: {e:#}");
    }
    std::fs::write(dir.join("report.md"), markdown(ch, report, flashable) + &notes)?;
    super::page::page(ch, report, dir)?.write(dir)?;
    Ok(())
}

fn markdown(ch: &Channels, r: &Report, flashable: bool) -> String {
    let mut s = String::new();
    let _ = writeln!(s, "# Discovery report\n");
    let _ = writeln!(s, "Start model: `{}`. Held-out rule: {}.\n", r.start.name(), r.heldout_rule);
    let _ = writeln!(s, "- Held-out gap before: {}", gaps_text(&r.heldout_gap_before));
    let _ = writeln!(s, "- Held-out gap after: {}", gaps_text(&r.heldout_gap_after));
    let _ =
        writeln!(s, "- Noise floor (bin-to-bin part of the final held-out residual): {}\n", gaps_text(&r.noise_floor));
    let labels = r.effect_labels();
    let _ = writeln!(
        s,
        "Summary: added {}; {}.\n",
        if labels.is_empty() { "none".to_string() } else { labels.join(", ") },
        if r.unexplained.is_empty() {
            "no structure left that the catalog fails to explain".to_string()
        } else {
            format!(
                "unexplained structure left on {}",
                r.unexplained.iter().map(|u| u.channel.as_str()).collect::<Vec<_>>().join(", ")
            )
        }
    );
    let _ = writeln!(s, "Selection: {}.\n", r.selection_rule);
    let unit = if ch.kind == LogKind::Cycling { "µg" } else { "value units" };
    let _ = writeln!(
        s,
        "## Peers on the same held-out split (bias channel, {unit})\n\nEach fitted per fold on the training bins (bin means of the raw temperature reading) and scored on the held-out bins.\n\n| model | held-out RMS |\n|---|---|"
    );
    let bias_gap = |g: &Gaps| match g {
        Gaps::Cycling { bias_ug, .. } => *bias_ug,
        Gaps::Single { value_rms } => *value_rms,
    };
    let _ = writeln!(s, "| start model (`{}`) | {:.4} |", r.start.name(), bias_gap(&r.heldout_gap_before));
    let _ = writeln!(s, "| discovered model | {:.4} |", bias_gap(&r.heldout_gap_after));
    for p in &r.peers {
        match (&p.heldout_rms, &p.error) {
            (Some(x), _) => {
                let _ = writeln!(s, "| {} | {x:.4} |", p.peer);
            }
            (None, e) => {
                let _ = writeln!(s, "| {} | not computed: {} |", p.peer, e.as_deref().unwrap_or("no figure"));
            }
        }
    }
    let _ = writeln!(s);
    if r.effects.is_empty() {
        let _ = writeln!(s, "## Effects added: none\n\nNo candidate improved the held-out fit significantly.\n");
    } else {
        let _ = writeln!(
            s,
            "## Effects added\n\n| # | effect | channel | parameters (95 % interval) | held-out gain ± block-bootstrap SE | held-out gap before → after | {} |\n|---|---|---|---|---|---|---|",
            if flashable { "in table.bin" } else { "root-crate slot" }
        );
        for (i, e) in r.effects.iter().enumerate() {
            let p: Vec<String> = e
                .params_ci
                .iter()
                .map(|(k, c)| {
                    format!(
                        "{k} = {:.4e} [{:.3e}, {:.3e}]{}",
                        c.value,
                        c.ci95[0],
                        c.ci95[1],
                        if c.at_bound { " **at search limit**" } else { "" }
                    )
                })
                .collect();
            let _ = writeln!(
                s,
                "| {} | `{}` | {} | {} | {:.1} ± {:.1} | {:.3} → {:.3} | {} |",
                i + 1,
                e.name,
                e.channel,
                p.join("; "),
                e.gain.gain,
                e.gain.bootstrap_se,
                e.heldout_gap_before,
                e.heldout_gap_after,
                if e.in_table { "yes" } else { "no (no root-crate slot)" }
            );
        }
        let _ = writeln!(s);
    }
    if !r.unexplained.is_empty() {
        let _ = writeln!(s, "## Unexplained\n");
        for u in &r.unexplained {
            let mut line = format!(
                "- The {} channel keeps structure that no catalog effect explains (held-out RMS {:.3}",
                u.channel, u.rms
            );
            match u.structure_rms {
                Some(x) if !u.correlates_with.is_empty() => {
                    let _ = write!(line, "; about {x:.3} of it follows {}).", u.correlates_with.join(", then "));
                }
                _ => line.push_str(")."),
            }
            if !u.where_.is_empty() {
                let _ = write!(line, " It is largest on {}.", u.where_);
            }
            if !u.pinned.is_empty() {
                let _ = write!(
                    line,
                    " Catalog effects that would fit only with a parameter at a search limit, so are not named: {}.",
                    u.pinned.join("; ")
                );
            }
            let _ = writeln!(s, "{line}");
        }
        let _ = writeln!(s);
    }
    let unit = if ch.kind == LogKind::Cycling { "ppm / µg" } else { "value units" };
    let _ = writeln!(
        s,
        "## Where the start model disagrees (held-out RMS, {unit})\n\n| channel | segment | RMS |\n|---|---|---|"
    );
    for w in &r.where_ {
        let _ = writeln!(s, "| {} | {} | {:.3} |", w.channel, w.segment, w.rms);
    }
    let _ = writeln!(s, "\n## Where the final model disagrees\n\n| channel | segment | RMS |\n|---|---|---|");
    for w in &r.where_after {
        let _ = writeln!(s, "| {} | {} | {:.3} |", w.channel, w.segment, w.rms);
    }
    let _ = writeln!(s, "\n## Candidates per round\n\nGain: drop of the held-out Σ(residual/RMS)² (units of one bin's variance); SE from the block sums; significant when gain/SE exceeds the critical value.\n");
    for (i, round) in r.rounds.iter().enumerate() {
        let _ = writeln!(s, "### Round {}\n\n| candidate | channel | gain | SE | gain/SE | critical | blocks × bins | significant | at search limit | held-out gaps |\n|---|---|---|---|---|---|---|---|---|---|", i + 1);
        for t in round {
            let _ = writeln!(
                s,
                "| `{}` | {} | {:.1} | {:.1} | {:.2} | {:.2} | {} × {} | {} | {} | {} |",
                t.name,
                t.channel,
                t.gain.gain,
                t.gain.se,
                t.gain.t,
                t.gain.critical,
                t.gain.blocks,
                t.gain.block_bins,
                if t.significant { "yes" } else { "no" },
                if t.at_bound.is_empty() { "-".to_string() } else { t.at_bound.join(", ") },
                gaps_text(&t.gaps)
            );
        }
        let _ = writeln!(s);
    }
    if flashable {
        let _ = writeln!(s, "Files: `report.json`, `table.bin` (root-crate table, 1 axis, rate window 32: `qfa-lab compensate --table DIR/table.bin`), `model.bin` (same bytes), `model.toml`, `residuals.csv`, `residual_*.png`.");
    } else {
        let _ = writeln!(s, "Files: `report.json`, `model.toml` (the named model, for reading: its K1 is 1 and `bias_drift` has no slot, so it is not a table to flash; the flashable table of all axes is `../table.bin`), `residuals.csv`, `residual_*.png`.");
    }
    s
}

struct Row {
    trace: usize,
    time_s: f64,
    temp_c: f64,
    dir: i8,
}

fn rows(ch: &Channels) -> Vec<Row> {
    let mut v = Vec::new();
    for (ti, t) in ch.traces.iter().enumerate() {
        for b in &t.bins {
            let m = (b.hi - b.lo) as f64;
            let tm = t.est_t[b.lo..b.hi].iter().map(|&x| f64::from(x)).sum::<f64>() / m;
            let rm = t.est_rate[b.lo..b.hi].iter().map(|&x| f64::from(x)).sum::<f64>() / m;
            let dir = if rm > 0.05 {
                1
            } else if rm < -0.05 {
                -1
            } else {
                0
            };
            v.push(Row { trace: ti, time_s: b.time_s, temp_c: tm, dir });
        }
    }
    v
}

fn write_csv(ch: &Channels, r: &Report, path: &Path) -> Result<()> {
    let (b, a) = &r.residuals;
    let mut s = String::from("program,time_s,temp_c,direction,sf_before_ppm,sf_after_ppm,bias_before,bias_after\n");
    for (i, row) in rows(ch).iter().enumerate() {
        let d = ["cooling", "hold", "heating"][(row.dir + 1) as usize];
        let _ = writeln!(
            s,
            "{},{:.1},{:.3},{d},{:.4},{:.4},{:.6},{:.6}",
            ch.traces[row.trace].program, row.time_s, row.temp_c, b.sf[i], a.sf[i], b.bias[i], a.bias[i]
        );
    }
    std::fs::write(path, s)?;
    Ok(())
}

fn plots(ch: &Channels, r: &Report, dir: &Path) -> Result<()> {
    crate::plot_font::register();
    let rows = rows(ch);
    let (b, a) = &r.residuals;
    let mut chans: Vec<(&str, &str, &Vec<f64>, &Vec<f64>)> = Vec::new();
    if ch.kind == LogKind::Cycling {
        chans.push(("scale_factor", "scale-factor residual, ppm", &b.sf, &a.sf));
        chans.push(("bias", "bias residual, µg", &b.bias, &a.bias));
    } else {
        chans.push(("value", "residual, value units", &b.bias, &a.bias));
    }
    // Program offsets so time runs on across programs.
    let mut off = vec![0.0; ch.traces.len()];
    let mut acc = 0.0;
    for (i, t) in ch.traces.iter().enumerate() {
        off[i] = acc;
        acc += t.time_s.last().copied().unwrap_or(0.0) / 3600.0 + 0.5;
    }
    for (name, label, before, after) in chans {
        for vs_time in [true, false] {
            let file = dir.join(format!("residual_{name}_vs_{}.png", if vs_time { "time" } else { "temp" }));
            let root = BitMapBackend::new(&file, (1200, 800)).into_drawing_area();
            root.fill(&WHITE)?;
            let panels = root.split_evenly((2, 1));
            let x_of = |i: usize| if vs_time { off[rows[i].trace] + rows[i].time_s / 3600.0 } else { rows[i].temp_c };
            let (xlo, xhi) =
                (0..rows.len()).map(x_of).fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), x| (l.min(x), h.max(x)));
            let ymax =
                before.iter().chain(after.iter()).filter(|v| v.is_finite()).fold(1e-12f64, |m, v| m.max(v.abs()));
            for (p, (title, v)) in
                panels.iter().zip([("before (start model)", before), ("after (discovered model)", after)])
            {
                let mut chart = ChartBuilder::on(p)
                    .caption(format!("{name} {title}: red heating, blue cooling, grey hold"), ("sans-serif", 18))
                    .margin(8)
                    .x_label_area_size(30)
                    .y_label_area_size(60)
                    .build_cartesian_2d(xlo..xhi.max(xlo + 1e-9), -ymax..ymax)?;
                chart
                    .configure_mesh()
                    .x_desc(if vs_time { "time, h (programs in sequence)" } else { "temperature, °C" })
                    .y_desc(label)
                    .draw()?;
                chart.draw_series((0..rows.len()).filter(|&i| v[i].is_finite()).map(|i| {
                    let c = match rows[i].dir {
                        1 => RED.mix(0.6),
                        -1 => BLUE.mix(0.6),
                        _ => BLACK.mix(0.3),
                    };
                    Circle::new((x_of(i), v[i]), 1, c.filled())
                }))?;
            }
            root.present()?;
        }
    }
    Ok(())
}
