//! `spherecal vn200 configure --board FILE [--serial DEV] [--current-baud B] [--save]` and
//! `spherecal vn200 emulate --serial DEV [--baud B]`.

use super::fail;
use crate::config::board::Board;
use crate::vn200::configure::{configure, Options};
use crate::vn200::emulator::{run as emulate, Unit};
use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::atomic::AtomicBool;

/// The VN-200 on a serial port.
#[derive(clap::Args, Debug)]
pub struct Args {
    #[command(subcommand)]
    pub what: What,
}

/// What to do.
#[derive(clap::Subcommand, Debug)]
pub enum What {
    /// Configure the unit for the board's `[ins]`: ASCII async output off, the binary output
    /// register 75 (fields, rate, port), each write checked against the unit's echo; then the
    /// first binary frames checked.
    Configure(ConfigureArgs),
    /// Be a VN-200 (factory settings: ASCII $VNYMR at 40 Hz) on a serial device, answering
    /// commands as the unit does; to try the rig without one (a socat pseudo-terminal pair).
    Emulate(EmulateArgs),
}

/// `vn200 configure`.
#[derive(clap::Args, Debug)]
pub struct ConfigureArgs {
    /// The board file.
    #[arg(long)]
    pub board: PathBuf,
    /// The serial device (default: the board's `ins.serial`).
    #[arg(long)]
    pub serial: Option<String>,
    /// The unit's baud now, when it is not the board's (factory: 115200): the board's is set
    /// through register 5 and this side follows.
    #[arg(long)]
    pub current_baud: Option<u32>,
    /// Write the settings to the unit's flash ($VNWNV) so that they survive a power cycle.
    #[arg(long)]
    pub save: bool,
}

/// `vn200 emulate`.
#[derive(clap::Args, Debug)]
pub struct EmulateArgs {
    /// The serial device to be the unit on.
    #[arg(long)]
    pub serial: String,
    /// Its baud.
    #[arg(long, default_value_t = 115_200)]
    pub baud: u32,
}

/// Run it.
pub fn run(a: Args) -> ExitCode {
    match a.what {
        What::Configure(c) => run_configure(c),
        What::Emulate(e) => run_emulate(e),
    }
}

fn run_configure(a: ConfigureArgs) -> ExitCode {
    let board = match Board::load(&a.board) {
        Ok(b) => b,
        Err(e) => return fail("vn200 configure", e),
    };
    let dev = a
        .serial
        .clone()
        .filter(|s| !s.is_empty())
        .unwrap_or_else(|| board.ins.serial.clone());
    if dev.is_empty() {
        return fail(
            "vn200 configure",
            "board: ins.serial is empty: give --serial DEV",
        );
    }
    let baud = a.current_baud.unwrap_or(board.ins.baud);
    let mut port = match serialport::new(dev.as_str(), baud)
        .timeout(std::time::Duration::from_millis(20))
        .open()
    {
        Ok(p) => p,
        Err(e) => return fail("vn200 configure", format!("serial {dev}: {e}")),
    };
    let opts = Options {
        current_baud: a.current_baud,
        save: a.save,
        ..Options::default()
    };
    match configure(&mut port, &dev, &board.ins, opts) {
        Ok(c) => {
            for s in &c.steps {
                sayln!("{dev}: {s}");
            }
            if c.retries > 0 {
                sayln!("{dev}: {} commands sent again", c.retries);
            }
            ExitCode::SUCCESS
        }
        Err(e) => fail("vn200 configure", e),
    }
}

fn run_emulate(a: EmulateArgs) -> ExitCode {
    let mut port = match serialport::new(a.serial.as_str(), a.baud)
        .timeout(std::time::Duration::from_millis(2))
        .open()
    {
        Ok(p) => p,
        Err(e) => return fail("vn200 emulate", format!("serial {}: {e}", a.serial)),
    };
    let unit = std::sync::Mutex::new(Unit::factory(a.baud));
    let stop = std::sync::Arc::new(AtomicBool::new(false));
    for sig in [signal_hook::consts::SIGINT, signal_hook::consts::SIGTERM] {
        if let Err(e) = signal_hook::flag::register(sig, std::sync::Arc::clone(&stop)) {
            return fail("vn200 emulate", format!("signal handler: {e}"));
        }
    }
    sayln!(
        "a VN-200 (factory settings) on {} at {} baud; Ctrl-C stops",
        a.serial,
        a.baud
    );
    let mut other = match port.try_clone() {
        Ok(p) => p,
        Err(e) => return fail("vn200 emulate", format!("serial {}: {e}", a.serial)),
    };
    let mut set_baud = |b: u32| {
        let _ = other.set_baud_rate(b);
    };
    emulate(&unit, &mut port, &mut set_baud, &stop);
    ExitCode::SUCCESS
}
