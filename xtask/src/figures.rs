//! The benchmark's figures: the budgets in `xtask/budgets.txt`, and the figures README.md and
//! docs/measurements.md state, against what the benchmark printed.

use super::*;

/// The budgets file (`name = limit` lines), relative to the repository root.
pub(super) const BUDGETS: &str = "xtask/budgets.txt";

/// `name = limit` lines; `#` starts a comment.
pub(super) fn parse_budgets(text: &str) -> Result<Vec<(String, u64)>> {
    let mut out = Vec::new();
    for (n, line) in text.lines().enumerate() {
        let line = line.split('#').next().unwrap_or("").trim();
        if line.is_empty() {
            continue;
        }
        let parsed = line.split_once('=').and_then(|(k, v)| Some((k.trim().to_string(), v.trim().parse().ok()?)));
        match parsed {
            Some(b) => out.push(b),
            None => return fail(format!("{BUDGETS}:{}: not `name = limit`: {line}", n + 1)),
        }
    }
    Ok(out)
}

/// Every budget against the `name=value` lines of `printed`: the lines over budget, or an
/// error for a budget whose figure was not printed (a budget nobody measures enforces nothing).
pub(super) fn over_budget(budgets: &[(String, u64)], printed: &str) -> Result<Vec<String>> {
    let mut over = Vec::new();
    for (name, limit) in budgets {
        let value = printed.lines().find_map(|l| l.strip_prefix(&format!("{name}="))?.trim().parse::<f64>().ok());
        match value {
            Some(v) if v > *limit as f64 => over.push(format!("{name}={v} is over its budget {limit}")),
            Some(_) => {}
            None => return fail(format!("no {name}= figure was printed to check against its budget")),
        }
    }
    Ok(over)
}

/// The firmware's figures the docs state: (printed key, the README row that gives it).
/// docs/measurements.md gives each in its table's row for the key, as the first number of
/// the "measured" cell; the README, anywhere in the row's value cell. Both are checked against what the benchmark prints today.
pub(super) const STATED_FIGURES: [(&str, &str); 7] = [
    ("fast_path_insns_3axis", "[fast path, 3 axes"),
    ("fast_path_insns_3axis_misalign", "[fast path, 3 axes"),
    ("slow_path_insns_sensor_per_axis", "[slow path, every slot on"),
    ("slow_path_insns_3axis_all_on", "[slow path, every slot on"),
    ("core_ram_bytes", "[RAM and flash of the core"),
    ("core_flash_bytes_static_table", "[RAM and flash of the core"),
    ("core_flash_bytes", "[RAM and flash of the core"),
];
pub(super) const MEASUREMENTS: &str = "docs/measurements.md";

/// A printed figure as the docs write it: thousands grouped by a space, a zero fraction
/// dropped (`1980.5` → `1 980.5`, `16056` → `16 056`, `28.0` → `28`).
pub(super) fn as_written(value: &str) -> String {
    let value = value.trim();
    let (int, frac) = value.split_once('.').unwrap_or((value, ""));
    let digits: Vec<char> = int.chars().collect();
    let mut out = String::new();
    for (i, c) in digits.iter().enumerate() {
        if i > 0 && (digits.len() - i).is_multiple_of(3) {
            out.push(' ');
        }
        out.push(*c);
    }
    if !frac.trim_end_matches('0').is_empty() {
        out.push('.');
        out.push_str(frac);
    }
    out
}

/// Whether `text` holds `figure` as a whole number: not inside a longer one, whether that
/// continues with digits, a decimal point or a space-grouped digit group ("1 980.5").
pub(super) fn holds_figure(text: &str, figure: &str) -> bool {
    let digit = |c: Option<char>| c.is_some_and(|c| c.is_ascii_digit());
    text.match_indices(figure).any(|(i, _)| {
        let mut back = text[..i].chars().rev();
        let (b1, b2) = (back.next(), back.next());
        let mut ahead = text[i + figure.len()..].chars();
        let (a1, a2) = (ahead.next(), ahead.next());
        let joined_before = digit(b1) || b1 == Some('.') || (b1 == Some(' ') && digit(b2));
        let joined_after = digit(a1) || ((a1 == Some('.') || a1 == Some(' ')) && digit(a2));
        !joined_before && !joined_after
    })
}

/// Each stated figure the README or docs/measurements.md gives differently from `printed`.
pub(super) fn stated_disagreements(readme: &str, measurements: &str, printed: &str) -> Result<Vec<String>> {
    let mut out = Vec::new();
    for (key, row) in STATED_FIGURES {
        let Some(value) = printed.lines().find_map(|l| l.strip_prefix(&format!("{key}="))) else {
            return fail(format!("no {key}= figure was printed to check the docs against"));
        };
        let figure = as_written(value);
        // The row's value cell only: its label holds numbers too ("3 axes").
        let value_cell = |l: &str| l.trim().trim_end_matches('|').rsplit(" | ").next().unwrap_or("").to_string();
        match readme.lines().find(|l| l.starts_with(&format!("| {row}"))).map(value_cell) {
            Some(c) if holds_figure(&c, &figure) => {}
            Some(c) => out.push(format!("README.md gives {key} not as {figure}: `{c}`")),
            None => out.push(format!("README.md has no row `| {row}` for {key}")),
        }
        let cell = measurements.lines().find(|l| l.starts_with(&format!("| `{key}`"))).and_then(|l| {
            let cells: Vec<&str> = l.trim().trim_matches('|').split(" | ").collect();
            cells.len().checked_sub(2).map(|i| cells[i].trim().trim_start_matches("**").to_string())
        });
        match cell {
            Some(c) if c.starts_with(&figure) && holds_figure(&c, &figure) => {}
            Some(c) => out.push(format!("{MEASUREMENTS} gives {key} as `{c}`, printed {figure}")),
            None => out.push(format!("{MEASUREMENTS} has no table row for `{key}`")),
        }
    }
    Ok(out)
}

/// Run the benchmark and size the core's flash: the figures, as `key=value` lines.
pub(super) fn measure_figures(overwrite: bool) -> Result<String> {
    let mut printed = String::new();
    step("benchmark example (examples/bench.rs), QEMU -icount shift=0");
    build_examples(&["bench", "size_baseline"])?;
    // The expected file pins which figures are printed; their values are judged below.
    printed.push_str(&run_snapshot(&BENCH_SNAPSHOT, &example_elf(BENCH_SNAPSHOT.program)?, true, overwrite)?);

    step("flash of the core: panic_check and static_table_link (core paths + runtime) minus size_baseline (runtime)");
    build_panic_check()?;
    build_panic_free(STATIC_TABLE_LINK)?;
    let tool = ensure_size_tool()?;
    let (ct, cd, cb) = berkeley(&tool, &example_elf(PANIC_CHECK)?)?;
    let (st, sd, sb) = berkeley(&tool, &example_elf(STATIC_TABLE_LINK)?)?;
    let (bt, bd, bb) = berkeley(&tool, &example_elf("size_baseline")?)?;
    println!(
        "panic_check: text={ct} data={cd} bss={cb}; static_table_link: text={st} data={sd} bss={sb}; \
         size_baseline: text={bt} data={bd} bss={bb}"
    );
    let core = format!(
        "core_flash_bytes={}\ncore_flash_bytes_static_table={}\ncore_static_ram_bytes={}\n",
        (ct + cd).saturating_sub(bt + bd),
        (st + sd).saturating_sub(bt + bd),
        (cd + cb).saturating_sub(bd + bb)
    );
    print!("{core}");
    printed.push_str(&core);
    Ok(printed)
}

/// Fail when a figure is over its budget or the docs state it differently.
pub(super) fn check_figures(printed: &str) -> Result {
    let read = |p: &str| std::fs::read_to_string(root().join(p)).map_err(|e| Failure(format!("{p}: {e}")));
    let budgets = parse_budgets(&read(BUDGETS)?)?;
    step(&format!("budgets ({BUDGETS}) and the figures README.md and {MEASUREMENTS} state"));
    let mut wrong = over_budget(&budgets, printed)?;
    wrong.extend(stated_disagreements(&read("README.md")?, &read(MEASUREMENTS)?, printed)?);
    if !wrong.is_empty() {
        return fail(format!("figures:\n{}", wrong.join("\n")));
    }
    println!("figures: all {} within their budgets; the {} the docs state match", budgets.len(), STATED_FIGURES.len());
    Ok(())
}

/// Build each firmware image (the board example and the apps) and print its flash and RAM
/// as `key=value` lines, which it returns for the budgets.
pub(super) fn firmware_figures() -> Result<String> {
    step("flash and RAM of the STM32F405 board example and apps (whole images, release)");
    let tool = ensure_size_tool()?;
    let mut lines = String::new();
    for (dir, bin, key) in FIRMWARES {
        run(firmware_cargo(dir, &["build", "--release", "--target", TARGET])?)?;
        let (t, d, b) = berkeley(&tool, &target_dir()?.join(TARGET).join("release").join(bin))?;
        println!("{bin}: text={t} data={d} bss={b}");
        lines.push_str(&format!("{key}_flash_bytes={}\n{key}_ram_bytes={}\n", t + d, d + b));
    }
    print!("{lines}");
    Ok(lines)
}

pub(super) fn bench_target(overwrite: bool) -> Result {
    ensure_target()?;
    let mut printed = measure_figures(overwrite)?;
    printed.push_str(&firmware_figures()?);
    check_figures(&printed)
}

/// Berkeley `text data bss` of an ELF.
pub(super) fn berkeley(tool: &Path, file: &Path) -> Result<(u64, u64, u64)> {
    let mut c = Command::new(tool);
    c.arg("-B").arg(file);
    let (status, out, err) = capture(c)?;
    if !status.success() {
        return fail(format!("{} {}: {err}", tool.display(), file.display()));
    }
    let nums: Vec<u64> =
        out.lines().nth(1).unwrap_or("").split_whitespace().take(3).filter_map(|w| w.parse().ok()).collect();
    match nums[..] {
        [t, d, b] => Ok((t, d, b)),
        _ => fail(format!("unexpected size output:\n{out}")),
    }
}
