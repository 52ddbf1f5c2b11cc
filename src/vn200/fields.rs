//! The binary output field table: every group and field of PROTOCOLS.md ("VectorNav binary
//! output"; VN-200 / VN-300 user manuals, section "Binary Output Groups"), with sizes and the
//! scalar components each field holds, named `Group.Field[.component]` as in the expected CSVs
//! of tests/data/vn200.
//!
//! A field is addressed by its group index and its bit in the group's 32-bit mask (bit 15 of the
//! first mask word says an extension word follows, whose bit k is field 16 + k).

/// A scalar type on the wire (all little-endian).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Ty {
    /// u8
    U8,
    /// i8
    I8,
    /// u16
    U16,
    /// i16
    I16,
    /// u32
    U32,
    /// u64
    U64,
    /// f32
    F32,
    /// f64
    F64,
}

impl Ty {
    /// Bytes on the wire.
    pub const fn size(self) -> usize {
        match self {
            Ty::U8 | Ty::I8 => 1,
            Ty::U16 | Ty::I16 => 2,
            Ty::U32 | Ty::F32 => 4,
            Ty::U64 | Ty::F64 => 8,
        }
    }
}

/// One scalar of a field. An empty name means the field is a single scalar.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Comp {
    /// Component name (`x`, `yaw`, `lat`, ...), or "" for a scalar field.
    pub name: &'static str,
    /// Wire type.
    pub ty: Ty,
}

/// How long a field is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Size {
    /// Always this many bytes.
    Fixed(u16),
    /// GNSS SatInfo: 2 + 8 N, N in the field's first byte.
    SatInfo,
    /// GNSS RawMeas: 12 + 28 N, N in the field's byte 10.
    RawMeas,
}

/// One field of a group.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct FieldDef {
    /// Field name within the group.
    pub name: &'static str,
    /// Wire size.
    pub size: Size,
    /// Scalars, in wire order (for variable fields: the fixed head only).
    pub comps: &'static [Comp],
}

/// The binary output groups, in group-byte bit order.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Group {
    /// Bit 0: Common.
    Common = 0,
    /// Bit 1: Time.
    Time = 1,
    /// Bit 2: IMU.
    Imu = 2,
    /// Bit 3: GNSS1.
    Gnss1 = 3,
    /// Bit 4: Attitude.
    Attitude = 4,
    /// Bit 5: INS.
    Ins = 5,
    /// Bit 6: GNSS2 (VN-300/310).
    Gnss2 = 6,
}

/// Number of groups we know (group-byte bits 0..6).
pub const GROUPS: usize = 7;

impl Group {
    /// All groups in bit order.
    pub const ALL: [Group; GROUPS] = [
        Group::Common,
        Group::Time,
        Group::Imu,
        Group::Gnss1,
        Group::Attitude,
        Group::Ins,
        Group::Gnss2,
    ];

    /// Name used in column names.
    pub const fn name(self) -> &'static str {
        match self {
            Group::Common => "Common",
            Group::Time => "Time",
            Group::Imu => "Imu",
            Group::Gnss1 => "Gnss1",
            Group::Attitude => "Attitude",
            Group::Ins => "Ins",
            Group::Gnss2 => "Gnss2",
        }
    }

    /// The group's field table, indexed by mask bit.
    pub const fn fields(self) -> &'static [Option<FieldDef>] {
        match self {
            Group::Common => COMMON,
            Group::Time => TIME,
            Group::Imu => IMU,
            Group::Gnss1 | Group::Gnss2 => GNSS,
            Group::Attitude => ATTITUDE,
            Group::Ins => INS,
        }
    }

    /// The definition of one field, if the bit names one we know.
    pub fn field(self, bit: u8) -> Option<&'static FieldDef> {
        self.fields().get(usize::from(bit)).and_then(Option::as_ref)
    }
}

const fn c(name: &'static str, ty: Ty) -> Comp {
    Comp { name, ty }
}
const fn f(name: &'static str, size: u16, comps: &'static [Comp]) -> Option<FieldDef> {
    Some(FieldDef {
        name,
        size: Size::Fixed(size),
        comps,
    })
}

const U64: &[Comp] = &[c("", Ty::U64)];
const U32: &[Comp] = &[c("", Ty::U32)];
const U16: &[Comp] = &[c("", Ty::U16)];
const U8: &[Comp] = &[c("", Ty::U8)];
const F32: &[Comp] = &[c("", Ty::F32)];
const F64: &[Comp] = &[c("", Ty::F64)];
const XYZ: &[Comp] = &[c("x", Ty::F32), c("y", Ty::F32), c("z", Ty::F32)];
const NED: &[Comp] = &[c("n", Ty::F32), c("e", Ty::F32), c("d", Ty::F32)];
const YPR: &[Comp] = &[c("yaw", Ty::F32), c("pitch", Ty::F32), c("roll", Ty::F32)];
const QUAT: &[Comp] = &[
    c("x", Ty::F32),
    c("y", Ty::F32),
    c("z", Ty::F32),
    c("w", Ty::F32),
];
const LLA: &[Comp] = &[c("lat", Ty::F64), c("lon", Ty::F64), c("alt", Ty::F64)];
const ECEF: &[Comp] = &[c("x", Ty::F64), c("y", Ty::F64), c("z", Ty::F64)];
const UTC: &[Comp] = &[
    c("year", Ty::I8),
    c("month", Ty::U8),
    c("day", Ty::U8),
    c("hour", Ty::U8),
    c("min", Ty::U8),
    c("sec", Ty::U8),
    c("ms", Ty::U16),
];
const IMU6: &[Comp] = &[
    c("accel_x", Ty::F32),
    c("accel_y", Ty::F32),
    c("accel_z", Ty::F32),
    c("rate_x", Ty::F32),
    c("rate_y", Ty::F32),
    c("rate_z", Ty::F32),
];
const MAGPRES: &[Comp] = &[
    c("mag_x", Ty::F32),
    c("mag_y", Ty::F32),
    c("mag_z", Ty::F32),
    c("temp", Ty::F32),
    c("pres", Ty::F32),
];
const DTHETAVEL: &[Comp] = &[
    c("dtime", Ty::F32),
    c("theta_x", Ty::F32),
    c("theta_y", Ty::F32),
    c("theta_z", Ty::F32),
    c("vel_x", Ty::F32),
    c("vel_y", Ty::F32),
    c("vel_z", Ty::F32),
];
const DTHETA: &[Comp] = &[
    c("dtime", Ty::F32),
    c("x", Ty::F32),
    c("y", Ty::F32),
    c("z", Ty::F32),
];
const DCM: &[Comp] = &[
    c("m0", Ty::F32),
    c("m1", Ty::F32),
    c("m2", Ty::F32),
    c("m3", Ty::F32),
    c("m4", Ty::F32),
    c("m5", Ty::F32),
    c("m6", Ty::F32),
    c("m7", Ty::F32),
    c("m8", Ty::F32),
];
const TIMEINFO: &[Comp] = &[c("status", Ty::U8), c("leap_seconds", Ty::I8)];
const DOP: &[Comp] = &[
    c("g", Ty::F32),
    c("p", Ty::F32),
    c("t", Ty::F32),
    c("v", Ty::F32),
    c("h", Ty::F32),
    c("n", Ty::F32),
    c("e", Ty::F32),
];
const HEAVE: &[Comp] = &[
    c("heave", Ty::F32),
    c("heave_rate", Ty::F32),
    c("delayed_heave", Ty::F32),
];
const SATINFO_HEAD: &[Comp] = &[c("num_sats", Ty::U8), c("resv", Ty::U8)];
const RAWMEAS_HEAD: &[Comp] = &[
    c("tow", Ty::F64),
    c("week", Ty::U16),
    c("num_meas", Ty::U8),
    c("resv", Ty::U8),
];
/// Bytes of one SatInfo entry and its scalars.
pub const SATINFO_ENTRY: &[Comp] = &[
    c("sys", Ty::I8),
    c("sv_id", Ty::U8),
    c("flags", Ty::U8),
    c("cno", Ty::U8),
    c("qi", Ty::U8),
    c("el", Ty::I8),
    c("az", Ty::I16),
];
/// Bytes of one RawMeas entry and its scalars.
pub const RAWMEAS_ENTRY: &[Comp] = &[
    c("sys", Ty::U8),
    c("sv_id", Ty::U8),
    c("freq", Ty::U8),
    c("chan", Ty::U8),
    c("slot", Ty::I8),
    c("cno", Ty::U8),
    c("flags", Ty::U16),
    c("pr", Ty::F64),
    c("cp", Ty::F64),
    c("dp", Ty::F32),
];
/// Fields whose contents PROTOCOLS.md gives only a size for: kept as raw bytes.
const RAW: &[Comp] = &[];

const COMMON: &[Option<FieldDef>] = &[
    f("TimeStartup", 8, U64),
    f("TimeGps", 8, U64),
    f("TimeSyncIn", 8, U64),
    f("YawPitchRoll", 12, YPR),
    f("Quaternion", 16, QUAT),
    f("AngularRate", 12, XYZ),
    f("Position", 24, LLA),
    f("VelNed", 12, NED),
    f("Accel", 12, XYZ),
    f("Imu", 24, IMU6),
    f("MagPres", 20, MAGPRES),
    f("DeltaThetaVel", 28, DTHETAVEL),
    f("InsStatus", 2, U16),
    f("SyncInCnt", 4, U32),
    f("TimeGpsPps", 8, U64),
];

const TIME: &[Option<FieldDef>] = &[
    f("TimeStartup", 8, U64),
    f("TimeGps", 8, U64),
    f("GpsTow", 8, U64),
    f("GpsWeek", 2, U16),
    f("TimeSyncIn", 8, U64),
    f("TimeGpsPps", 8, U64),
    f("TimeUtc", 8, UTC),
    f("SyncInCnt", 4, U32),
    f("SyncOutCnt", 4, U32),
    f("TimeStatus", 1, U8),
];

const IMU: &[Option<FieldDef>] = &[
    f("ImuStatus", 2, U16),
    f("UncompMag", 12, XYZ),
    f("UncompAccel", 12, XYZ),
    f("UncompGyro", 12, XYZ),
    f("Temp", 4, F32),
    f("Pres", 4, F32),
    f("DeltaTheta", 16, DTHETA),
    f("DeltaVel", 12, XYZ),
    f("Mag", 12, XYZ),
    f("Accel", 12, XYZ),
    f("AngularRate", 12, XYZ),
    f("SensSat", 2, U16),
    f("Raw12", 40, RAW),
];

const GNSS: &[Option<FieldDef>] = &[
    f("Utc", 8, UTC),
    f("Tow", 8, U64),
    f("Week", 2, U16),
    f("NumSats", 1, U8),
    f("Fix", 1, U8),
    f("PosLla", 24, LLA),
    f("PosEcef", 24, ECEF),
    f("VelNed", 12, NED),
    f("VelEcef", 12, XYZ),
    f("PosU", 12, NED),
    f("VelU", 4, F32),
    f("TimeU", 4, F32),
    f("TimeInfo", 2, TIMEINFO),
    f("Dop", 28, DOP),
    Some(FieldDef {
        name: "SatInfo",
        size: Size::SatInfo,
        comps: SATINFO_HEAD,
    }),
    None,
    Some(FieldDef {
        name: "RawMeas",
        size: Size::RawMeas,
        comps: RAWMEAS_HEAD,
    }),
    f("Status", 2, U16),
    f("AltMsl", 8, F64),
];

const ATTITUDE: &[Option<FieldDef>] = &[
    f("VpeStatus", 2, U16),
    f("YawPitchRoll", 12, YPR),
    f("Quaternion", 16, QUAT),
    f("Dcm", 36, DCM),
    f("MagNed", 12, NED),
    f("AccelNed", 12, NED),
    f("LinearAccelBody", 12, XYZ),
    f("LinearAccelNed", 12, NED),
    f("YprU", 12, YPR),
    f("Raw9", 12, RAW),
    f("Raw10", 28, RAW),
    f("Raw11", 24, RAW),
    f("Heave", 12, HEAVE),
    f("AttU", 4, F32),
];

const INS: &[Option<FieldDef>] = &[
    f("InsStatus", 2, U16),
    f("PosLla", 24, LLA),
    f("PosEcef", 24, ECEF),
    f("VelBody", 12, XYZ),
    f("VelNed", 12, NED),
    f("VelEcef", 12, XYZ),
    f("MagEcef", 12, XYZ),
    f("AccelEcef", 12, XYZ),
    f("LinearAccelEcef", 12, XYZ),
    f("PosU", 4, F32),
    f("VelU", 4, F32),
    f("Raw11", 68, RAW),
    f("Raw12", 64, RAW),
];

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn component_sizes_add_up_to_the_field_size() {
        for g in Group::ALL {
            for (bit, def) in g.fields().iter().enumerate() {
                let Some(def) = def else { continue };
                let sum: usize = def.comps.iter().map(|c| c.ty.size()).sum();
                match def.size {
                    Size::Fixed(n) if def.comps.is_empty() => assert!(n > 0),
                    Size::Fixed(n) => {
                        assert_eq!(sum, usize::from(n), "{}.{} (bit {bit})", g.name(), def.name)
                    }
                    Size::SatInfo => assert_eq!(sum, 2),
                    Size::RawMeas => assert_eq!(sum, 12),
                }
            }
        }
        assert_eq!(SATINFO_ENTRY.iter().map(|c| c.ty.size()).sum::<usize>(), 8);
        assert_eq!(RAWMEAS_ENTRY.iter().map(|c| c.ty.size()).sum::<usize>(), 28);
    }

    #[test]
    fn sizes_match_protocols_md() {
        // PROTOCOLS.md, "Field sizes", group by group.
        let sizes = |g: Group| -> [u16; 19] {
            let mut out = [0; 19];
            for (i, d) in g.fields().iter().enumerate() {
                out[i] = match d {
                    Some(FieldDef {
                        size: Size::Fixed(n),
                        ..
                    }) => *n,
                    Some(_) => 1,
                    None => 0,
                };
            }
            out
        };
        assert_eq!(
            sizes(Group::Common)[..15],
            [8, 8, 8, 12, 16, 12, 24, 12, 12, 24, 20, 28, 2, 4, 8]
        );
        assert_eq!(sizes(Group::Time)[..10], [8, 8, 8, 2, 8, 8, 8, 4, 4, 1]);
        assert_eq!(
            sizes(Group::Imu)[..13],
            [2, 12, 12, 12, 4, 4, 16, 12, 12, 12, 12, 2, 40]
        );
        assert_eq!(
            sizes(Group::Gnss1),
            [8, 8, 2, 1, 1, 24, 24, 12, 12, 12, 4, 4, 2, 28, 1, 0, 1, 2, 8]
        );
        assert_eq!(
            sizes(Group::Attitude)[..14],
            [2, 12, 16, 36, 12, 12, 12, 12, 12, 12, 28, 24, 12, 4]
        );
        assert_eq!(
            sizes(Group::Ins)[..13],
            [2, 24, 24, 12, 12, 12, 12, 12, 12, 4, 4, 68, 64]
        );
    }
}
