//! The tools the steps need (the Cortex-M target, QEMU, Chromium, a `size` for ARM), found
//! or installed.

use super::*;

pub(super) fn found(program: &str, arg: &str) -> bool {
    Command::new(program).arg(arg).stdout(Stdio::null()).stderr(Stdio::null()).status().is_ok_and(|s| s.success())
}

pub(super) fn is_root_with_apt() -> bool {
    let uid = Command::new("id").arg("-u").output().ok().map(|o| String::from_utf8_lossy(&o.stdout).trim().to_owned());
    uid.as_deref() == Some("0") && found("apt-get", "--version")
}

/// Run an apt install line as root, or fail with the exact command to run.
pub(super) fn apt_install(what: &str, line: &str) -> Result {
    if !is_root_with_apt() {
        return fail(format!("{what} is missing; install it with:\n    {line}"));
    }
    println!("{what} is missing: installing it (root, apt available)");
    let mut c = Command::new("sh");
    c.args(["-c", line]).env("DEBIAN_FRONTEND", "noninteractive");
    run(c)
}

pub(super) fn ensure_target() -> Result {
    step(&format!("rustup target {TARGET}"));
    let mut c = Command::new("rustup");
    c.current_dir(root()).args(["target", "list", "--installed"]);
    let (status, out, err) = capture(c)?;
    if !status.success() {
        return fail(format!("`rustup target list --installed` failed: {err}"));
    }
    if out.lines().any(|l| l.trim() == TARGET) {
        println!("{TARGET} is installed");
        return Ok(());
    }
    let mut c = Command::new("rustup");
    c.current_dir(root()).args(["target", "add", TARGET]);
    run(c)
}

pub(super) fn ensure_qemu() -> Result {
    if found(QEMU, "--version") {
        return Ok(());
    }
    apt_install(QEMU, QEMU_INSTALL)?;
    if found(QEMU, "--version") {
        Ok(())
    } else {
        fail(format!("{QEMU} still missing after `{QEMU_INSTALL}`"))
    }
}

/// Chromium for the lab's page tests (`lab/tests/report_html.rs`): installed as root with
/// apt; otherwise missing is a failure under `CI=true`, and elsewhere those tests print
/// SKIPPED (said here too, loudly).
pub(super) fn ensure_chromium() -> Result {
    if found(CHROMIUM, "--version") || env::var_os("QFA_CHROMIUM").is_some() {
        return Ok(());
    }
    if is_root_with_apt() || env::var("CI").as_deref() == Ok("true") {
        apt_install(CHROMIUM, CHROMIUM_INSTALL)?;
        return if found(CHROMIUM, "--version") {
            Ok(())
        } else {
            fail(format!("{CHROMIUM} still missing after `{CHROMIUM_INSTALL}`"))
        };
    }
    println!(
        "\n*** {CHROMIUM} is missing: the lab's report.html browser checks will print SKIPPED; install it with:\n    \
         {CHROMIUM_INSTALL} ***\n"
    );
    Ok(())
}

/// A size tool printing Berkeley format: llvm-size, arm-none-eabi-size, or rustup's llvm-tools.
pub(super) fn ensure_size_tool() -> Result<PathBuf> {
    for t in ["llvm-size", "arm-none-eabi-size"] {
        if found(t, "--version") {
            return Ok(PathBuf::from(t));
        }
    }
    let llvm_tools = || -> Option<PathBuf> {
        let o = Command::new("rustc").current_dir(root()).args(["--print", "sysroot"]).output().ok()?;
        let sysroot = PathBuf::from(String::from_utf8_lossy(&o.stdout).trim());
        let o = Command::new("rustc").current_dir(root()).arg("-vV").output().ok()?;
        let text = String::from_utf8_lossy(&o.stdout).into_owned();
        let host = text.lines().find_map(|l| l.strip_prefix("host: "))?.trim().to_owned();
        let p = sysroot.join("lib/rustlib").join(host).join("bin/llvm-size");
        p.exists().then_some(p)
    };
    if let Some(p) = llvm_tools() {
        return Ok(p);
    }
    apt_install("a size tool (llvm-size or arm-none-eabi-size)", SIZE_INSTALL)?;
    if found("arm-none-eabi-size", "--version") {
        Ok(PathBuf::from("arm-none-eabi-size"))
    } else {
        fail(format!("arm-none-eabi-size still missing after `{SIZE_INSTALL}`"))
    }
}
