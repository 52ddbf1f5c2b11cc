//! The point cloud data packet view: a checked [`DataPacket`] over the UDP payload, every
//! multi-byte field little-endian (PandarXT-32 manual 3.1.2, PandarQT manual 3.1.2, QT128C2X
//! manual 3.1.2).
//!
//! ```text
//! pre-header  0 SOP 0xEE 0xFF | 2 protocol major, minor | 4 reserved
//! header      6 channels | 7 blocks | 8 first block return | 9 distance unit [mm] |
//!             10 returns | 11 flags (bit 0: UDP sequence present)
//! body        per block: azimuth u16 [0.01 deg], then per channel: distance u16 [unit],
//!             reflectivity u8, reserved u8
//! QT128 only  body CRC-32/MPEG-2 u32 | functional safety (17 B)
//! tail        XT (24 B): 10 return mode | 11 motor speed u16 [rpm] | 13 date-time (year -
//!                 1900, month, day, hour, minute, second) | 19 microseconds u32 | 23 factory
//!             QT64 (24 B): 10 motor speed | 12 microseconds | 16 return mode | 17 factory |
//!                 18 date-time
//!             QT128 (34 B): 5 mode flag (bit 0: firing sequence 1) | 12 return mode | 13 motor
//!                 speed | 15 date-time | 21 microseconds | 25 factory | 26 UDP sequence u32 |
//!                 30 CRC-32/MPEG-2 of the tail before it
//! sequence    XT, QT64: u32 (when flagged); QT128: a 32-byte signature may follow the tail
//! ```

use super::Error;
use crate::le::{le16, le32};

/// Where the header's fields are.
mod field {
    pub const MAJOR: usize = 2;
    pub const MINOR: usize = 3;
    pub const CHANNELS: usize = 6;
    pub const BLOCKS: usize = 7;
    pub const DIS_UNIT: usize = 9;
    pub const FLAGS: usize = 11;
    /// The body's start.
    pub const BODY: usize = 12;
    /// A channel's bytes: distance u16, reflectivity, reserved.
    pub const UNIT: usize = 4;
    /// The tail's length.
    pub const TAIL: usize = 24;
}

/// A model this view reads, told by the header's protocol version, channels and blocks.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Model {
    /// PandarXT16: protocol 6.1, 16 channels, 8 blocks.
    Xt16,
    /// PandarXT32: protocol 6.1, 32 channels, 8 blocks.
    Xt32,
    /// PandarQT64: protocol 3.1, 64 channels, 4 blocks.
    Qt64,
    /// PandarQT128 (QT128C2X): protocol 3.2, 128 channels, 2 blocks.
    Qt128,
}

/// The QT128C2X's firing time of each channel in firing sequences 1 and 2 after its block's
/// start [ns] (the unit's firetime correction file, as tier4/nebula tabulates it; 0: the
/// channel does not fire in that sequence).
const QT128_LOOPS: [[u32; 128]; 2] = [
    [
        0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0,
        0, 0, 27656, 53000, 2312, 78344, 81512, 5480, 56168, 30824, 33992, 59336, 8648, 84680,
        87848, 11816, 62504, 37160, 40328, 65672, 14984, 91016, 94184, 18152, 68840, 43496, 46664,
        72008, 21320, 97352, 100520, 24488, 75176, 49832, 1456, 77488, 26800, 52144, 55312, 29968,
        80656, 4624, 7792, 83824, 33136, 58480, 61648, 36304, 86992, 10960, 14128, 90160, 39472,
        64816, 67984, 42640, 93328, 17296, 20464, 96496, 45808, 71152, 74320, 48976, 99664, 23632,
        25944, 51288, 600, 76632, 79800, 3768, 54456, 29112, 32280, 57624, 6936, 82968, 86136,
        10104, 60792, 35448, 38616, 63960, 13272, 89304, 92472, 16440, 67128, 41784, 44952, 70296,
        19608, 95640, 98808, 22776, 73464, 48120,
    ],
    [
        2312, 78344, 27656, 53000, 56168, 30824, 81512, 5480, 8648, 84680, 33992, 59336, 62504,
        37160, 87848, 11816, 14984, 91016, 40328, 65672, 68840, 43496, 94184, 18152, 21320, 97352,
        46664, 72008, 75176, 49832, 100520, 24488, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0,
        0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 600, 76632, 25944, 51288, 54456, 29112,
        79800, 3768, 6936, 82968, 32280, 57624, 60792, 35448, 86136, 10104, 13272, 89304, 38616,
        63960, 67128, 41784, 92472, 16440, 19608, 95640, 44952, 70296, 73464, 48120, 98808, 22776,
        26800, 52144, 1456, 77488, 80656, 4624, 55312, 29968, 33136, 58480, 7792, 83824, 86992,
        10960, 61648, 36304, 39472, 64816, 14128, 90160, 93328, 17296, 67984, 42640, 45808, 71152,
        20464, 96496, 99664, 23632, 74320, 48976,
    ],
];

/// CRC-32/MPEG-2 of the QT128's body and tail.
const CRC32: crc::Crc<u32> = crc::Crc::<u32>::new(&crc::CRC_32_MPEG_2);

/// PandarQT64's channel firing offsets from its block's start [ns] (PandarQT manual, appendix
/// "Laser Firing Time"; tier4/nebula's table prints channel 56 as 12960, a dropped digit: the
/// offsets rise with the channel).
const QT64_FIRING_NS: [u32; 64] = [
    12310, 14370, 16430, 18490, 20540, 22600, 24660, 26710, 29160, 31220, 33280, 35340, 37390,
    39450, 41500, 43560, 46610, 48670, 50730, 52780, 54840, 56900, 58950, 61010, 63450, 65520,
    67580, 69630, 71690, 73740, 75800, 77860, 80900, 82970, 85020, 87080, 89140, 91190, 93250,
    95300, 97750, 99820, 101870, 103930, 105980, 108040, 110100, 112150, 115200, 117260, 119320,
    121380, 123430, 125490, 127540, 129600, 132050, 134110, 136170, 138220, 140280, 142340, 144390,
    146450,
];

impl Model {
    /// The model of a header's protocol version, channels and blocks.
    pub fn of(version: [u8; 2], channels: u8, blocks: u8) -> Option<Self> {
        match (version, channels, blocks) {
            ([6, 1], 16, 8) => Some(Model::Xt16),
            ([6, 1], 32, 8) => Some(Model::Xt32),
            ([3, 1], 64, 4) => Some(Model::Qt64),
            ([3, 2], 128, 2) => Some(Model::Qt128),
            _ => None,
        }
    }

    /// The model of a correction file's channel count.
    pub fn of_channels(n: usize) -> Option<Self> {
        match n {
            16 => Some(Model::Xt16),
            32 => Some(Model::Xt32),
            64 => Some(Model::Qt64),
            128 => Some(Model::Qt128),
            _ => None,
        }
    }

    /// Time between two firings of one channel [ns]: 50 us (XT), 166.67 us (QT64), two
    /// firings of 111.11 us (QT128: each channel fires in one of its two sequences).
    pub const fn laser_period_ns(self) -> u32 {
        match self {
            Model::Xt16 | Model::Xt32 => 50_000,
            Model::Qt64 => 166_667,
            Model::Qt128 => 222_220,
        }
    }

    /// Channels.
    pub const fn channels(self) -> usize {
        match self {
            Model::Xt16 => 16,
            Model::Xt32 => 32,
            Model::Qt64 => 64,
            Model::Qt128 => 128,
        }
    }

    /// Blocks per packet.
    pub const fn blocks(self) -> usize {
        match self {
            Model::Xt16 | Model::Xt32 => 8,
            Model::Qt64 => 4,
            Model::Qt128 => 2,
        }
    }

    /// The name Hesai gives it.
    pub const fn name(self) -> &'static str {
        match self {
            Model::Xt16 => "PandarXT16",
            Model::Xt32 => "PandarXT32",
            Model::Qt64 => "PandarQT64",
            Model::Qt128 => "PandarQT128",
        }
    }

    /// A block's bytes: azimuth and the channels'.
    const fn block_len(self) -> usize {
        2 + self.channels() * field::UNIT
    }

    /// Where the body ends.
    const fn body_end(self) -> usize {
        field::BODY + self.blocks() * self.block_len()
    }

    /// Where the tail starts (after the QT128's body CRC and functional safety).
    const fn tail_at(self) -> usize {
        match self {
            Model::Qt128 => self.body_end() + 4 + 17,
            _ => self.body_end(),
        }
    }

    /// The packet's length without what is optional (the XT's and QT64's UDP sequence, the
    /// QT128's signature).
    pub const fn packet_len(self) -> usize {
        match self {
            Model::Qt128 => self.tail_at() + 34,
            _ => self.tail_at() + field::TAIL,
        }
    }

    /// The tail's offsets of the return mode, motor speed, date-time and microseconds.
    const fn tail_fields(self) -> [usize; 4] {
        match self {
            Model::Xt16 | Model::Xt32 => [10, 11, 13, 19],
            Model::Qt64 => [16, 10, 18, 12],
            Model::Qt128 => [12, 13, 15, 21],
        }
    }

    /// The firing time of channel `ch` in block `b` after the packet's absolute time [ns],
    /// `returns` blocks per firing, the QT128's firing `sequence` (1 or 2) (manual appendix
    /// "Absolute Time and Laser Firing Time": an XT's absolute time is the trigger of the
    /// firing in its last block(s), firings 50 us apart, the channel 0.368 us + 1.512 us (XT32)
    /// or 3.024 us (XT16) per channel after the block's start 5.632 us; a QT64's is the start of
    /// its first block, firings 166.67 us apart, 25.71 us + the channel's offset; a QT128's
    /// blocks start 9 us and (single return) 9 + 111.11 us after it, each channel at its
    /// sequence's offset, as tier4/nebula times them). Negative: before the absolute time.
    pub fn firing_offset_ns(self, b: usize, ch: usize, returns: usize, sequence: u8) -> i64 {
        let returns = returns.max(1);
        match self {
            Model::Xt16 | Model::Xt32 => {
                let per = if self == Model::Xt16 { 3024 } else { 1512 };
                let firing = (self.blocks() - 1 - b.min(self.blocks() - 1)) / returns;
                5632 - 50_000 * firing as i64 + 368 + per * ch as i64
            }
            Model::Qt64 => {
                let firing = (b / returns) as i64;
                25_710 + 500_000 * firing / 3 + i64::from(QT64_FIRING_NS[ch % 64])
            }
            Model::Qt128 => {
                // Single return: block 1 fires 111.11 us after block 2; dual: one firing fills
                // both blocks.
                let later = (1 - b.min(1) as i64) / returns as i64;
                let table = &QT128_LOOPS[usize::from(sequence == 2)];
                9000 + 111_110 * later + i64::from(table[ch % 128])
            }
        }
    }
}

/// The tail's return mode (manual 3.1.2 "Tail").
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ReturnMode {
    /// Single return: first (0x33), second (0x34), strongest (0x37) or last (0x38).
    Single(u8),
    /// Two returns per firing in adjacent blocks: last and strongest (0x39), first and second
    /// (0x3a), first and last (0x3b), first and strongest (0x3c), strongest and second strongest
    /// (0x3e).
    Dual(u8),
}

impl ReturnMode {
    /// The tail's byte as a mode.
    pub fn of(b: u8) -> Result<Self, Error> {
        match b {
            0x33 | 0x34 | 0x37 | 0x38 => Ok(ReturnMode::Single(b)),
            0x39..=0x3c | 0x3e => Ok(ReturnMode::Dual(b)),
            found => Err(Error::ReturnMode { found }),
        }
    }

    /// Blocks per firing.
    pub fn returns(self) -> usize {
        match self {
            ReturnMode::Single(_) => 1,
            ReturnMode::Dual(_) => 2,
        }
    }

    /// The manual's name of the mode.
    pub fn name(self) -> &'static str {
        match self {
            ReturnMode::Single(0x33) => "first",
            ReturnMode::Single(0x34) => "second",
            ReturnMode::Single(0x37) => "strongest",
            ReturnMode::Single(_) => "last",
            ReturnMode::Dual(0x39) => "dual (last, strongest)",
            ReturnMode::Dual(0x3a) => "dual (first, second)",
            ReturnMode::Dual(0x3b) => "dual (first, last)",
            ReturnMode::Dual(0x3c) => "dual (first, strongest)",
            ReturnMode::Dual(_) => "dual (strongest, second strongest)",
        }
    }
}

/// A data packet of a known [`Model`]. Built with [`DataPacket::new_checked`], every accessor
/// is infallible: block and channel indices are reduced modulo the model's counts.
#[derive(Debug, Clone, Copy)]
pub struct DataPacket<T: AsRef<[u8]>> {
    buffer: T,
    model: Model,
    mode: ReturnMode,
}

impl<T: AsRef<[u8]>> DataPacket<T> {
    /// Wrap `buffer`: the pre-header's start, a known layout, its exact length (with the UDP
    /// sequence when the header's flag says so) and a known return mode.
    pub fn new_checked(buffer: T) -> Result<Self, Error> {
        let b = buffer.as_ref();
        if b.len() < field::BODY {
            return Err(Error::Length {
                expected: field::BODY,
                got: b.len(),
            });
        }
        if b[0] != 0xEE || b[1] != 0xFF {
            return Err(Error::Start {
                found: [b[0], b[1]],
            });
        }
        let version = [b[field::MAJOR], b[field::MINOR]];
        let (channels, blocks) = (b[field::CHANNELS], b[field::BLOCKS]);
        let model = Model::of(version, channels, blocks).ok_or(Error::Layout {
            version,
            channels,
            blocks,
        })?;
        let optional = match model {
            Model::Qt128 => [0, 32],
            _ if b[field::FLAGS] & 1 == 1 => [4, 4],
            _ => [0, 0],
        };
        if !optional.iter().any(|o| b.len() == model.packet_len() + o) {
            return Err(Error::Length {
                expected: model.packet_len() + optional[0],
                got: b.len(),
            });
        }
        let mode = ReturnMode::of(b[model.tail_at() + model.tail_fields()[0]])?;
        Ok(Self {
            buffer,
            model,
            mode,
        })
    }

    fn bytes(&self) -> &[u8] {
        self.buffer.as_ref()
    }

    /// The packet's bytes.
    pub fn as_bytes(&self) -> &[u8] {
        self.buffer.as_ref()
    }

    /// The model the header says.
    pub fn model(&self) -> Model {
        self.model
    }

    /// The return mode the tail says.
    pub fn return_mode(&self) -> ReturnMode {
        self.mode
    }

    /// The distance unit [mm] (the XT and QT send 4).
    pub fn distance_unit_mm(&self) -> u8 {
        self.bytes()[field::DIS_UNIT]
    }

    fn block_at(&self, b: usize) -> usize {
        field::BODY + (b % self.model.blocks()) * self.model.block_len()
    }

    /// Block `b`'s azimuth [0.01 deg] (the rotor's at the block's firing).
    pub fn azimuth(&self, b: usize) -> u16 {
        le16(self.bytes(), self.block_at(b))
    }

    /// Channel `ch`'s return in block `b`: distance [the distance unit; 0: none] and
    /// reflectivity.
    pub fn unit(&self, b: usize, ch: usize) -> (u16, u8) {
        let at = self.block_at(b) + 2 + (ch % self.model.channels()) * field::UNIT;
        let s = self.bytes();
        (le16(s, at), s[at + 2])
    }

    fn tail(&self) -> &[u8] {
        &self.bytes()[self.model.tail_at()..self.model.packet_len()]
    }

    /// The motor speed [rpm].
    pub fn motor_rpm(&self) -> u16 {
        le16(self.tail(), self.model.tail_fields()[1])
    }

    /// The UTC date and time to the second, as sent: year since 1900, month, day, hour,
    /// minute, second.
    pub fn date_time(&self) -> [u8; 6] {
        let at = self.model.tail_fields()[2];
        let mut d = [0u8; 6];
        d.copy_from_slice(&self.tail()[at..at + 6]);
        d
    }

    /// The microseconds of the absolute time within its second.
    pub fn micros(&self) -> u32 {
        le32(self.tail(), self.model.tail_fields()[3])
    }

    /// The packet's absolute time [ns since 1970, UTC]: the date-time plus the microseconds
    /// (manual appendix "Absolute Time"); `None` when the date-time is not a date (month 0,
    /// hour 24 ...) or the microseconds reach a second.
    pub fn unix_ns(&self) -> Option<i64> {
        let [y, mo, d, h, mi, s] = self.date_time();
        let micros = self.micros();
        if micros >= 1_000_000 {
            return None;
        }
        let t = super::date_time(1900 + i32::from(y), [mo, d, h, mi, s])?;
        Some(t.unix_seconds() * 1_000_000_000 + i64::from(micros) * 1000)
    }

    /// The UDP sequence number, when the header says it is sent (the QT128 always sends it).
    pub fn udp_sequence(&self) -> Option<u32> {
        let s = self.bytes();
        match self.model {
            Model::Qt128 => Some(le32(self.tail(), 26)),
            _ => (s[field::FLAGS] & 1 == 1).then(|| le32(s, self.model.packet_len())),
        }
    }

    /// Channel `ch`'s firing time in block `b` after the packet's absolute time [ns]
    /// ([`Model::firing_offset_ns`]; the QT128's firing sequence: in single return block 1
    /// fires sequence 1 and block 2 sequence 2, in dual return the tail's mode flag says).
    pub fn firing_offset_ns(&self, b: usize, ch: usize) -> i64 {
        let returns = self.mode.returns();
        let sequence = match (self.model, returns) {
            (Model::Qt128, 1) => 1 + (b % 2) as u8,
            (Model::Qt128, _) if self.tail()[5] & 1 == 1 => 1,
            (Model::Qt128, _) => 2,
            _ => 1,
        };
        self.model.firing_offset_ns(b, ch, returns, sequence)
    }

    /// The QT128's CRC-32/MPEG-2 of its body and of its tail: (stored, computed) each; `None`
    /// for the models that send none.
    pub fn crc(&self) -> Option<[(u32, u32); 2]> {
        if self.model != Model::Qt128 {
            return None;
        }
        let (s, end) = (self.bytes(), self.model.body_end());
        let t = self.tail();
        Some([
            (le32(s, end), CRC32.checksum(&s[field::BODY..end])),
            (le32(t, 30), CRC32.checksum(&t[..30])),
        ])
    }
}

impl Model {
    /// The header's protocol version.
    const fn version(self) -> [u8; 2] {
        match self {
            Model::Xt16 | Model::Xt32 => [6, 1],
            Model::Qt64 => [3, 1],
            Model::Qt128 => [3, 2],
        }
    }

    /// The length of a packet [`DataPacket::emit`] writes: with the UDP sequence (the XT's and
    /// QT64's flagged one; the QT128's is in its tail) and no signature.
    pub const fn emitted_len(self) -> usize {
        match self {
            Model::Qt128 => self.packet_len(),
            _ => self.packet_len() + 4,
        }
    }
}

/// The emit side: what a unit writes (the simulator).
impl<T: AsRef<[u8]> + AsMut<[u8]>> DataPacket<T> {
    /// Write an empty packet of `model` in `mode` into `buffer` (exactly
    /// [`Model::emitted_len`] bytes, else `None`): the pre-header, header (distance unit 4 mm,
    /// the UDP sequence flagged), no return in any block, the tail's return mode and
    /// `sequence`. The fields are then set; [`Self::seal`] last.
    pub fn emit(mut buffer: T, model: Model, mode: ReturnMode, sequence: u32) -> Option<Self> {
        let b = buffer.as_mut();
        if b.len() != model.emitted_len() {
            return None;
        }
        b.fill(0);
        let [major, minor] = model.version();
        b[..field::BODY].copy_from_slice(&[
            0xEE,
            0xFF,
            major,
            minor,
            0,
            0,
            model.channels() as u8,
            model.blocks() as u8,
            1,
            4,
            mode.returns() as u8,
            u8::from(model != Model::Qt128),
        ]);
        let (tail, [m, ..]) = (model.tail_at(), model.tail_fields());
        b[tail + m] = match mode {
            ReturnMode::Single(x) | ReturnMode::Dual(x) => x,
        };
        match model {
            Model::Qt128 => b[tail + 26..tail + 30].copy_from_slice(&sequence.to_le_bytes()),
            _ => b[model.packet_len()..].copy_from_slice(&sequence.to_le_bytes()),
        }
        Some(Self {
            buffer,
            model,
            mode,
        })
    }

    fn bytes_mut(&mut self) -> &mut [u8] {
        self.buffer.as_mut()
    }

    /// Set block `b`'s azimuth [0.01 deg].
    pub fn set_azimuth(&mut self, b: usize, centideg: u16) {
        let at = self.block_at(b);
        self.bytes_mut()[at..at + 2].copy_from_slice(&centideg.to_le_bytes());
    }

    /// Set channel `ch`'s return in block `b`: distance [4 mm; 0: none] and reflectivity.
    pub fn set_unit(&mut self, b: usize, ch: usize, distance: u16, reflectivity: u8) {
        let at = self.block_at(b) + 2 + (ch % self.model.channels()) * field::UNIT;
        let s = self.bytes_mut();
        s[at..at + 2].copy_from_slice(&distance.to_le_bytes());
        s[at + 2] = reflectivity;
    }

    /// Set the tail's motor speed [rpm], UTC date-time (year since 1900, month, day, hour,
    /// minute, second) and microseconds within the second.
    pub fn set_time(&mut self, rpm: u16, date_time: [u8; 6], micros: u32) {
        let (tail, [_, r, d, us]) = (self.model.tail_at(), self.model.tail_fields());
        let s = self.bytes_mut();
        s[tail + r..tail + r + 2].copy_from_slice(&rpm.to_le_bytes());
        s[tail + d..tail + d + 6].copy_from_slice(&date_time);
        s[tail + us..tail + us + 4].copy_from_slice(&micros.to_le_bytes());
    }

    /// The QT128's CRCs of its body and tail (nothing for the others): call last.
    pub fn seal(&mut self) {
        if self.model != Model::Qt128 {
            return;
        }
        let (end, tail) = (self.model.body_end(), self.model.tail_at());
        let s = self.bytes_mut();
        let body = CRC32.checksum(&s[field::BODY..end]);
        s[end..end + 4].copy_from_slice(&body.to_le_bytes());
        let t = CRC32.checksum(&s[tail..tail + 30]);
        s[tail + 30..tail + 34].copy_from_slice(&t.to_le_bytes());
    }
}
