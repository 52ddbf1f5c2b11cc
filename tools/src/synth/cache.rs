//! One synthesis per built-in scenario per test run: with `SPHERECAL_SYNTH_CACHE=DIR` (the test
//! command, `scripts/test.sh`, sets it to a folder of its own run and removes it after)
//! [`super::synth`] copies a built-in scenario's files from DIR when it was synthesised before in
//! the run, and stores what it writes there otherwise. A dozen tests synthesise `table1` as it
//! is; the simulator is deterministic (every random stream seeded by the scenario), so the copy
//! is byte for byte what it would write. The key is the scenario as TOML (its seed included)
//! and the crate's version. Only a scenario equal to the built-in of its name is stored (the
//! tests' edited variants are each used once or twice: storing them would hold gigabytes).
//! Any failure of the cache only costs the synthesis it would have saved.

use super::Truth;
use crate::config::scenario::Scenario;
use std::path::{Path, PathBuf};

/// The environment variable naming the cache's folder.
pub const VAR: &str = "SPHERECAL_SYNTH_CACHE";

/// This scenario's place in the cache at `root`, if it is a built-in one as it is.
pub fn slot(root: &Path, s: &Scenario) -> Option<PathBuf> {
    let text = toml::to_string(s).ok()?;
    let builtin = Scenario::load(&s.name).ok()?;
    if s.trajectory.file.is_some() || toml::to_string(&builtin).ok()? != text {
        return None;
    }
    // FNV-1a, 64 bits, over the TOML and the version: a key, not a check.
    let bytes = text.bytes().chain(env!("CARGO_PKG_VERSION").bytes());
    let h = bytes.fold(0xcbf2_9ce4_8422_2325u64, |h, b| {
        (h ^ u64::from(b)).wrapping_mul(0x0100_0000_01b3)
    });
    Some(root.join(format!("{}-{h:016x}", s.name)))
}

/// The scenario's files copied from its slot into `dir`, and its truth; `None` when the slot
/// is empty (or unreadable).
pub fn fetch(slot: &Path, dir: &Path) -> Option<Truth> {
    let names: Vec<_> = std::fs::read_dir(slot)
        .ok()?
        .filter_map(|e| e.ok().map(|e| e.file_name()))
        .collect();
    std::fs::create_dir_all(dir).ok()?;
    for n in &names {
        std::fs::copy(slot.join(n), dir.join(n)).ok()?;
    }
    serde_json::from_str(&std::fs::read_to_string(dir.join("truth.json")).ok()?).ok()
}

/// Store `files` (what the synthesis wrote) in the slot: copied to a folder of this call's own
/// (process and call number: threads of one process store too) and renamed into place, so that
/// a concurrent reader sees all of them or none.
pub fn store(slot: &Path, files: &[PathBuf]) {
    static CALLS: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);
    let (Some(root), Some(name)) = (slot.parent(), slot.file_name()) else {
        return;
    };
    let tmp = root.join(format!(
        ".{}-{}-{}",
        name.to_string_lossy(),
        std::process::id(),
        CALLS.fetch_add(1, std::sync::atomic::Ordering::Relaxed)
    ));
    let copied = std::fs::create_dir_all(&tmp).is_ok()
        && files.iter().all(|f| {
            f.file_name()
                .is_some_and(|n| std::fs::copy(f, tmp.join(n)).is_ok())
        });
    if !(copied && std::fs::rename(&tmp, slot).is_ok()) {
        let _ = std::fs::remove_dir_all(&tmp);
    }
}

#[cfg(test)]
mod tests {
    use super::super::{synth_cached, Truth};
    use super::*;

    fn files(dir: &Path) -> Vec<(String, Vec<u8>)> {
        let mut v: Vec<_> = std::fs::read_dir(dir)
            .unwrap()
            .map(|e| {
                let e = e.unwrap();
                (
                    e.file_name().to_string_lossy().into_owned(),
                    std::fs::read(e.path()).unwrap(),
                )
            })
            .collect();
        v.sort();
        v
    }

    /// A built-in scenario is stored once and then copied: byte for byte what the simulator
    /// writes without the cache, the same truth; an edited one is never stored.
    #[test]
    fn a_builtin_is_copied_byte_for_byte_and_an_edit_is_not_stored() {
        let base = std::env::temp_dir().join(format!("spherecal-cache-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&base);
        let root = base.join("cache");
        std::fs::create_dir_all(&root).unwrap();
        let s = Scenario::load("table1-bare").unwrap();
        let plain = synth_cached(&s, &base.join("plain"), None).unwrap();
        assert_eq!(std::fs::read_dir(&root).unwrap().count(), 0);
        let first = synth_cached(&s, &base.join("first"), Some(&root)).unwrap();
        let slot = slot(&root, &s).unwrap();
        assert!(slot.is_dir());
        // A marker in the slot shows that the second comes from it.
        std::fs::write(slot.join("marker"), b"cached").unwrap();
        let second = synth_cached(&s, &base.join("second"), Some(&root)).unwrap();
        assert!(base.join("second/marker").is_file());
        std::fs::remove_file(base.join("second/marker")).unwrap();
        let want = files(&base.join("plain"));
        assert!(want.iter().any(|(n, _)| n == "lidar.pcap"));
        assert!(want == files(&base.join("first")) && want == files(&base.join("second")));
        assert!(plain == first && first == second, "{:?}", (plain, second));
        // Another seed: not the built-in, not stored.
        let mut other = s.clone();
        other.seed += 1;
        assert!(super::slot(&root, &other).is_none());
        let _: Truth = synth_cached(&other, &base.join("other"), Some(&root)).unwrap();
        assert_eq!(std::fs::read_dir(&root).unwrap().count(), 1);
        std::fs::remove_dir_all(&base).unwrap();
    }
}
