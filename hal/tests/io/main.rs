//! The I/O boundary's tests: one binary for the capture reader, the serial and UDP sources
//! and the real VLP-16 captures against independent decodings.

mod common;

mod pcap_files;
mod serial_pty;
mod udp_loopback;
mod vlp16_real_captures;
