//! The VN-200 on the serial line: configuring it from a board ([`configure`]) and an emulated
//! unit that answers as the real one does ([`emulator`]), for tests and for trying the rig.

pub mod configure;
pub mod emulator;
