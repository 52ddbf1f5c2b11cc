//! `spherecal ins FILE [--csv OUT]`: frame a VN-200 serial capture (raw bytes or our timestamped
//! serial log), count what it holds, and list the binary frames' decoded fields.

use spherecal::vn200::ascii::Vn;
use spherecal::vn200::binary::{Frame, Value};
use spherecal::vn200::{Framer, Item, Pose, Stats};
use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::io::{self, Write};

/// Column name of one scalar: `Group.Field[.component]` (tests/data/vn200/*.expected.csv).
pub fn column_name(group: &str, field: &str, comp: &str) -> String {
    if comp.is_empty() {
        format!("{group}.{field}")
    } else {
        format!("{group}.{field}.{comp}")
    }
}

/// Where a column sorts: group, field bit, component index (wire order).
pub type ColumnKey = (u8, u8, usize);

/// The named scalars of a frame, in wire order.
pub fn frame_columns(f: &Frame<'_>) -> Vec<(ColumnKey, String, Value)> {
    let mut out = Vec::new();
    for field in f.fields() {
        for (i, (c, v)) in field.scalars().enumerate() {
            let key = (field.group as u8, field.bit, i);
            out.push((
                key,
                column_name(field.group.name(), field.def.name, c.name),
                v,
            ));
        }
    }
    out
}

/// Frame all of `bytes` (then flush at the end of the input) and hand every item to `f`.
pub fn for_each_item(bytes: &[u8], mut f: impl FnMut(spherecal::vn200::Framed<'_>)) -> Stats {
    let mut framer: Box<Framer> = Box::default();
    framer.consume(bytes, &mut f);
    framer.finish();
    while let Some(it) = framer.next() {
        f(it);
    }
    *framer.stats()
}

/// What a file held.
#[derive(Debug, Default, Clone)]
pub struct InsSummary {
    /// Framer counts.
    pub stats: Stats,
    /// Binary frames by header (group byte and masks, hex).
    pub frames_by_header: BTreeMap<String, u64>,
    /// ASCII sentences by name (`VNINS`, `GPRMC`, ...).
    pub sentences: BTreeMap<String, u64>,
    /// Frames and sentences that carried a complete pose.
    pub poses: u64,
    /// Their times: span, clock steps, time going back ([`crate::state::InsState`]).
    pub clock: crate::state::InsState,
    /// First rejected item: offset and reason.
    pub first_error: Option<(u64, String)>,
}

fn hex(b: &[u8]) -> String {
    b.iter()
        .fold(String::with_capacity(2 * b.len()), |mut s, x| {
            let _ = write!(s, "{x:02x}");
            s
        })
}

/// Frame `bytes`; with `csv`, write one row per binary frame (columns: `offset,header,len`, then
/// every scalar any frame of the file carries, in group/field order).
pub fn frame_bytes(bytes: &[u8], csv: Option<&mut dyn Write>) -> io::Result<InsSummary> {
    let mut s = InsSummary::default();
    // First pass: counts and the union of columns.
    let mut columns: BTreeMap<ColumnKey, String> = BTreeMap::new();
    s.stats = for_each_item(bytes, |it| match it.item {
        Item::Binary(f) => {
            *s.frames_by_header.entry(hex(f.header_bytes())).or_default() += 1;
            if let Some(p) = Pose::from_frame(&f) {
                s.poses += 1;
                s.clock
                    .sample_frame(p.time, it.offset, f.bytes().len(), f.time_startup());
                s.clock.used(p.time, i64::MAX);
            }
            for (key, name, _) in frame_columns(&f) {
                columns.entry(key).or_insert(name);
            }
        }
        Item::Ascii(a) | Item::Nmea(a) => {
            *s.sentences.entry(a.name().to_string()).or_default() += 1;
            if let Ok(Vn::Ins(ins)) = a.decode() {
                if let Some(p) = Pose::from_ins(&ins) {
                    s.poses += 1;
                    s.clock.sample(p.time, false, None);
                    s.clock.used(p.time, i64::MAX);
                }
            }
        }
        Item::Error(e) => {
            s.first_error.get_or_insert((it.offset, e.to_string()));
        }
    });

    let Some(w) = csv else { return Ok(s) };
    write!(w, "offset,header,len")?;
    for c in columns.values() {
        write!(w, ",{c}")?;
    }
    writeln!(w)?;
    let index: BTreeMap<ColumnKey, usize> =
        columns.keys().enumerate().map(|(i, k)| (*k, i)).collect();
    let mut row = vec![String::new(); columns.len()];
    let mut result = Ok(());
    for_each_item(bytes, |it| {
        if let Item::Binary(f) = it.item {
            row.iter_mut().for_each(String::clear);
            for (key, _, v) in frame_columns(&f) {
                if let Some(&i) = index.get(&key) {
                    row[i] = v.to_string();
                }
            }
            if result.is_ok() {
                result = writeln!(
                    w,
                    "{},{},{},{}",
                    it.offset,
                    hex(f.header_bytes()),
                    f.bytes().len(),
                    row.join(",")
                );
            }
        }
    });
    result?;
    w.flush()?;
    Ok(s)
}

impl InsSummary {
    /// The human summary `spherecal ins` prints.
    pub fn render(&self, path: &str) -> String {
        let st = &self.stats;
        let mut o = String::new();
        let _ = writeln!(o, "file: {path}");
        let _ = writeln!(o, "binary frames: {}", st.frames);
        for (h, n) in &self.frames_by_header {
            let _ = writeln!(o, "  header {h}: {n}");
        }
        let _ = writeln!(o, "CRC failures: {}", st.crc_failures);
        let _ = writeln!(
            o,
            "ASCII $VN sentences: {} (bad checksum: {})",
            st.ascii, st.ascii_bad_checksum
        );
        let _ = writeln!(
            o,
            "NMEA sentences: {} (decoded by the nmea crate: {})",
            st.nmea, st.nmea_decoded
        );
        for (n, c) in &self.sentences {
            let _ = writeln!(o, "  {n}: {c}");
        }
        let _ = writeln!(o, "poses: {}", self.poses);
        let c = &self.clock;
        if let Some((a, b)) = c.span {
            let _ = writeln!(
                o,
                "pose times: {:.3} s from GPS {a:.3} s; clock steps: {}{}{}",
                b - a,
                c.clock_step_count,
                c.clock_steps
                    .iter()
                    .take(4)
                    .map(|(t, d)| format!(" ({d:+.4} s at {:.3} s)", t - a))
                    .collect::<String>(),
                if c.backward > 0 {
                    format!("; time went back {} times", c.backward)
                } else {
                    String::new()
                }
            );
        }
        let _ = writeln!(
            o,
            "skipped bytes: {} (unknown headers at 0xFA: {}, too long: {})",
            st.skipped_bytes, st.bad_headers, st.too_long
        );
        if let Some((off, e)) = &self.first_error {
            let _ = writeln!(o, "first rejected item at byte {off}: {e}");
        }
        o
    }
}
