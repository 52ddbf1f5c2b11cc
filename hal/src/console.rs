//! The rig's console: status lines to a serial port (a terminal on the rig's console port, or
//! a pseudo-terminal in tests) or to stdout. Each line ends in CR LF, as serial terminals
//! expect, and is flushed at once.

use std::io::{self, Write};

/// A line sink.
pub struct Console {
    out: Box<dyn Write + Send>,
    /// Lines written.
    pub lines: u64,
}

impl Console {
    /// `stdout`, or a serial device at `baud` (8N1).
    pub fn open(device: &str, baud: u32) -> Result<Self, String> {
        if device == "stdout" {
            return Ok(Self::new(Box::new(io::stdout())));
        }
        let port = serialport::new(device, baud)
            .open()
            .map_err(|e| format!("console {device}: {e}"))?;
        Ok(Self::new(Box::new(port)))
    }

    /// Any writer.
    pub fn new(out: Box<dyn Write + Send>) -> Self {
        Self { out, lines: 0 }
    }

    /// Write one line (without its line end) and flush.
    pub fn write_line(&mut self, line: &str) -> io::Result<()> {
        self.out.write_all(line.as_bytes())?;
        self.out.write_all(b"\r\n")?;
        self.out.flush()?;
        self.lines += 1;
        Ok(())
    }
}
