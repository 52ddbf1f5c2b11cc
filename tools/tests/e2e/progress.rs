//! Progress bars: drawn on a terminal (a pseudo-terminal through util-linux `script`, part of
//! every Debian), never into a pipe or a log.

use crate::common;

#[test]
fn bars_on_a_terminal_only() {
    let out = common::tmp("progress", "synth");
    let bin = env!("CARGO_BIN_EXE_spherecal");
    let cmd = format!("{bin} synth --scenario table1-bare --out {}", out.display());
    // On a terminal; synthesised, not copied from the test run's cache.
    let tty = std::process::Command::new("script")
        .args(["-qec", &cmd, "/dev/null"])
        .env_remove(spherecal_tools::synth::cache::VAR)
        .output()
        .expect("util-linux script");
    assert!(tty.status.success());
    let text = String::from_utf8_lossy(&tty.stdout);
    assert!(text.contains("simulating data packets ["), "{text}");
    // Into a pipe: nothing on standard error.
    let piped = common::spherecal()
        .args(["synth", "--scenario", "table1-bare", "--out"])
        .arg(&out)
        .output()
        .unwrap();
    assert!(piped.status.success());
    assert!(
        piped.stderr.is_empty(),
        "{}",
        String::from_utf8_lossy(&piped.stderr)
    );
    assert!(!String::from_utf8_lossy(&piped.stdout).contains('\x1b'));
}
