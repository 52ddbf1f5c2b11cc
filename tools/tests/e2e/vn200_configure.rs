//! `spherecal vn200 configure` against an emulated VN-200 on a pseudo-terminal that answers as
//! the unit does (tools/src/vn200/emulator.rs): the factory unit is configured and checked
//! (ASCII off, register 75 as the board says, binary frames arriving with its fields), a
//! garbled line is retried, a baud change is followed, `--save` writes flash; an output the
//! baud cannot carry, a silent unit and a missing device are refused in words.

use crate::common;

use serialport::{SerialPort, TTYPort};
use spherecal_tools::config::board::Board;
use spherecal_tools::vn200::configure::binary_output;
use spherecal_tools::vn200::emulator::{run, Unit};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;

/// The rig board with its serial device and baud replaced.
fn board(dir: &std::path::Path, baud: u32) -> std::path::PathBuf {
    let text = std::fs::read_to_string(common::repo_root().join("boards/rig-vn200.toml"))
        .unwrap()
        .replace("baud = 921600", &format!("baud = {baud}"));
    let p = dir.join(format!("board-{baud}.toml"));
    std::fs::write(&p, text).unwrap();
    p
}

/// Run `vn200 configure` with `args` against `unit` on a fresh pseudo-terminal pair; returns
/// the exit code, stdout + stderr, and the unit afterwards.
fn configure(unit: Unit, args: &[&str], board: &std::path::Path) -> (Option<i32>, String, Unit) {
    let (mut master, slave) = TTYPort::pair().expect("a pseudo-terminal pair");
    master.set_timeout(Duration::from_millis(2)).unwrap();
    let name = slave.name().unwrap();
    let unit = Arc::new(Mutex::new(unit));
    let stop = Arc::new(AtomicBool::new(false));
    let (u2, s2) = (Arc::clone(&unit), Arc::clone(&stop));
    let emu = std::thread::spawn(move || run(&u2, &mut master, &mut |_| {}, &s2));
    let out = common::spherecal()
        .args(["vn200", "configure", "--board"])
        .arg(board)
        .args(["--serial", &name])
        .args(args)
        .output()
        .unwrap();
    stop.store(true, Ordering::Relaxed);
    emu.join().unwrap();
    drop(slave);
    let text =
        String::from_utf8_lossy(&out.stdout).to_string() + &String::from_utf8_lossy(&out.stderr);
    let u = unit.lock().unwrap().clone();
    (out.status.code(), text, u)
}

#[test]
fn configures_an_emulated_unit_and_refuses_in_words() {
    let dir = common::tmp("vn200", "x");
    std::fs::create_dir_all(&dir).unwrap();
    let b921 = board(&dir, 921_600);
    let want = binary_output(&Board::load(&b921).unwrap().ins).unwrap();

    // The factory unit (ASCII $VNYMR at 40 Hz, no binary output) at the board's baud.
    let (code, text, u) = configure(Unit::factory(921_600), &[], &b921);
    assert_eq!(code, Some(0), "{text}");
    assert_eq!(u.async_type, 0, "ASCII output off");
    assert_eq!(u.binary[0], want, "register 75 as the board says");
    assert!(text.contains("binary output (register 75): TimeStartup, TimeGps, YawPitchRoll, Position, InsStatus, Attitude.YprU, Ins.PosU at 200 Hz on serial port 1"), "{text}");
    assert!(
        text.contains("first binary frames match the board"),
        "{text}"
    );
    assert!(!u.saved);

    // A line that garbles the first two commands: sent again, then configured.
    let mut garbling = Unit::factory(921_600);
    garbling.garble_first = 2;
    let (code, text, u) = configure(garbling, &[], &b921);
    assert_eq!(code, Some(0), "{text}");
    assert!(text.contains("2 commands sent again"), "{text}");
    assert_eq!(u.binary[0], want);

    // A factory unit at 115200: the board's 921600 set first, this side following; saved.
    let (code, text, u) = configure(
        Unit::factory(115_200),
        &["--current-baud", "115200", "--save"],
        &b921,
    );
    assert_eq!(code, Some(0), "{text}");
    assert_eq!(u.baud, 921_600);
    assert!(text.contains("baud 115200 -> 921600"), "{text}");
    assert!(u.saved && text.contains("saved to flash"), "{text}");

    // 200 Hz of 60-byte frames need 120 kbit/s: at 9600 baud the unit says $VNERR,0C.
    let b9600 = board(&dir, 9600);
    let (code, text, _) = configure(Unit::factory(9600), &[], &b9600);
    assert_eq!(code, Some(2), "{text}");
    assert!(
        text.contains("register 75")
            && text.contains("$VNERR,0C")
            && text.contains("insufficient baud rate"),
        "{text}"
    );

    // A unit that is off.
    let mut mute = Unit::factory(921_600);
    mute.mute = true;
    let (code, text, u) = configure(mute, &[], &b921);
    assert_eq!(code, Some(2), "{text}");
    assert!(text.contains("no answer after 3 tries"), "{text}");
    assert_eq!(u.commands, 3);

    // No such device.
    let out = common::spherecal()
        .args(["vn200", "configure", "--board"])
        .arg(&b921)
        .args(["--serial", "/dev/nonexistent-vn200"])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("/dev/nonexistent-vn200"));
}
