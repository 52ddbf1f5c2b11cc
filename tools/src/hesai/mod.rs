//! Hesai PandarXT16 / XT32 / QT64 / QT128 captures and bags: the unit's angle correction file
//! ([`corrections`]) and the decoding of its packets with it ([`decode`]).

pub mod corrections;
pub mod decode;
