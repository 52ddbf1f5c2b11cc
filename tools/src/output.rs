//! Outputs written whole or not at all.
//!
//! A file a command writes goes first to a hidden temporary beside it (`.NAME.partial`), which
//! [`Staged::commit`] renames over the final name once every byte is out. Dropped without a
//! commit (an error on the way), or when the process is interrupted with SIGINT/SIGTERM after
//! [`remove_partial_on_interrupt`], the temporary is removed: a reader (a surveyor's `decode`,
//! a viewer polling a report) never sees half a file under the final name. Rename within one
//! folder is atomic on POSIX file systems.
//!
//! [`check`] tries an output's place before a long run (the folder exists and takes a new file,
//! the name is not a folder), so that a read-only mount is found in a second, not at the end.

use std::fs::File;
use std::io::{BufWriter, Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};

/// Temporaries being written, removed on an interrupt.
static PENDING: Mutex<Vec<PathBuf>> = Mutex::new(Vec::new());
/// Outputs this run has committed, removed too on an interrupt before [`finished`]: one run's
/// outputs are all there or none (a report.json beside no LAS would describe a run that did
/// not end).
static COMMITTED: Mutex<Vec<PathBuf>> = Mutex::new(Vec::new());

fn pending() -> std::sync::MutexGuard<'static, Vec<PathBuf>> {
    PENDING.lock().unwrap_or_else(|e| e.into_inner())
}

fn committed() -> std::sync::MutexGuard<'static, Vec<PathBuf>> {
    COMMITTED.lock().unwrap_or_else(|e| e.into_inner())
}

/// Every output of the run is written: an interrupt from now on removes none of them.
pub fn finished() {
    committed().clear();
}

/// On an interrupt: remove the temporaries being written and the outputs committed so far;
/// the words naming what was removed.
fn remove_this_run() -> String {
    let tmps = std::mem::take(&mut *pending());
    let done = std::mem::take(&mut *committed());
    let mut named = Vec::new();
    for f in &done {
        if std::fs::remove_file(f).is_ok() {
            named.push(f.display().to_string());
        }
    }
    for t in &tmps {
        if std::fs::remove_file(t).is_ok() {
            // The final name of `.NAME.partial`.
            let name = t
                .file_name()
                .map(|n| n.to_string_lossy().into_owned())
                .unwrap_or_default();
            let fin = name
                .strip_prefix('.')
                .and_then(|n| n.strip_suffix(".partial"))
                .unwrap_or(&name)
                .to_string();
            named.push(format!("{} (unfinished)", t.with_file_name(fin).display()));
        }
    }
    if named.is_empty() {
        "interrupted: no output was written".into()
    } else {
        format!(
            "interrupted: removed {}: a run's outputs are all there or none",
            named.join(", ")
        )
    }
}

/// The temporary beside `p`: `.NAME.partial` in the same folder (hidden, so that a glob of the
/// outputs does not take it).
pub fn partial_path(p: &Path) -> PathBuf {
    let name = p
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| "output".into());
    p.with_file_name(format!(".{name}.partial"))
}

/// `p` can be written: its folder exists and takes a new file (tried by creating and removing
/// the temporary), and `p` is not a folder. `flag` names the option in the message.
pub fn check(flag: &str, p: &Path) -> Result<(), crate::Error> {
    let what = |why: String| {
        if flag.is_empty() {
            format!("{}: {why}", p.display())
        } else {
            format!("{flag} {}: {why}", p.display())
        }
    };
    if p.is_dir() {
        return Err(what("is a folder, not a file".into()).into());
    }
    let dir = match p.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    if !dir.is_dir() {
        return Err(what(format!("the folder {} does not exist", dir.display())).into());
    }
    let tmp = partial_path(p);
    match File::create(&tmp) {
        Ok(_) => {
            let _ = std::fs::remove_file(&tmp);
            Ok(())
        }
        Err(e) => Err(what(format!("cannot write in the folder {}: {e}", dir.display())).into()),
    }
}

/// On SIGINT or SIGTERM, remove every temporary being written and every output this run
/// committed before [`finished`], say which, and exit (130 or 143, as a shell reports a
/// signal). For the file commands; the rig handles its signals itself.
pub fn remove_partial_on_interrupt() {
    use signal_hook::consts::{SIGINT, SIGTERM};
    static INSTALLED: std::sync::Once = std::sync::Once::new();
    INSTALLED.call_once(|| {
        let Ok(mut signals) = signal_hook::iterator::Signals::new([SIGINT, SIGTERM]) else {
            return;
        };
        std::thread::spawn(move || {
            if let Some(sig) = signals.forever().next() {
                eprintln!("{}", remove_this_run());
                std::process::exit(128 + sig);
            }
        });
    });
}

/// A file being written under its temporary name (see the module's doc).
///
/// After its first I/O error (or once [`Staged::abandon`]ed) it discards what follows, so that
/// a writer that finishes its format in `Drop` (the `las` crate's does, and panics when that
/// fails) finishes quietly; [`Staged::commit`] then gives the first error.
#[derive(Debug)]
pub struct Staged {
    path: PathBuf,
    tmp: PathBuf,
    w: Option<BufWriter<File>>,
    failed: Option<String>,
    abandoned: Arc<AtomicBool>,
}

/// Abandons a [`Staged`] output from outside the writer that owns it.
#[derive(Debug, Clone)]
pub struct Abandon(Arc<AtomicBool>);

impl Abandon {
    /// From now on the output discards what it is given and is not committed.
    pub fn abandon(&self) {
        self.0.store(true, Ordering::Relaxed);
    }
}

impl Staged {
    /// Start writing `p` (through `.NAME.partial`).
    pub fn create(p: &Path) -> Result<Self, crate::Error> {
        let tmp = partial_path(p);
        pending().push(tmp.clone());
        let f = File::create(&tmp).map_err(|e| {
            pending().retain(|x| x != &tmp);
            format!("{}: cannot create: {e}", p.display())
        })?;
        Ok(Self {
            path: p.to_path_buf(),
            tmp,
            w: Some(BufWriter::with_capacity(1 << 20, f)),
            failed: None,
            abandoned: Arc::new(AtomicBool::new(false)),
        })
    }

    /// A handle that abandons this output (for the owner of a writer wrapping it).
    pub fn abandon_handle(&self) -> Abandon {
        Abandon(Arc::clone(&self.abandoned))
    }

    /// Discard what follows; the temporary is removed and nothing is committed.
    pub fn abandon(&mut self) {
        self.abandoned.store(true, Ordering::Relaxed);
    }

    fn discarding(&self) -> bool {
        self.failed.is_some() || self.abandoned.load(Ordering::Relaxed)
    }

    /// Run one operation on the file, latching its first error.
    fn io<R>(
        &mut self,
        otherwise: R,
        f: impl FnOnce(&mut BufWriter<File>) -> std::io::Result<R>,
    ) -> std::io::Result<R> {
        if self.discarding() {
            return Ok(otherwise);
        }
        let Some(w) = self.w.as_mut() else {
            return Err(std::io::Error::other("output already committed"));
        };
        f(w).inspect_err(|e| self.failed = Some(e.to_string()))
    }

    /// The final path.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Flush, and rename the temporary to the final name (or give the first error; an
    /// abandoned output is not written).
    pub fn commit(mut self) -> Result<(), crate::Error> {
        if let Some(e) = &self.failed {
            return Err(format!("{}: {e}", self.path.display()).into());
        }
        if self.abandoned.load(Ordering::Relaxed) {
            return Err(format!("{}: abandoned", self.path.display()).into());
        }
        let err = |e: std::io::Error| format!("{}: {e}", self.path.display());
        if let Some(w) = self.w.take() {
            let f = w.into_inner().map_err(|e| err(e.into_error()))?;
            f.sync_all().map_err(err)?;
        }
        std::fs::rename(&self.tmp, &self.path).map_err(err)?;
        pending().retain(|x| x != &self.tmp);
        committed().push(self.path.clone());
        Ok(())
    }
}

impl Write for Staged {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        self.io(buf.len(), |w| w.write(buf))
    }
    fn write_all(&mut self, buf: &[u8]) -> std::io::Result<()> {
        self.io((), |w| w.write_all(buf))
    }
    fn flush(&mut self) -> std::io::Result<()> {
        self.io((), |w| w.flush())
    }
}

impl Seek for Staged {
    fn seek(&mut self, pos: SeekFrom) -> std::io::Result<u64> {
        self.io(0, |w| w.seek(pos))
    }
}

impl Drop for Staged {
    fn drop(&mut self) {
        if self.w.take().is_some() || self.tmp.exists() {
            let _ = std::fs::remove_file(&self.tmp);
        }
        pending().retain(|x| x != &self.tmp);
    }
}

/// Write `bytes` to `p` whole or not at all.
pub fn write(p: &Path, bytes: &[u8]) -> Result<(), crate::Error> {
    let mut s = Staged::create(p)?;
    s.write_all(bytes)
        .map_err(|e| format!("{}: {e}", p.display()))?;
    s.commit()
}

/// Commit several staged files together (after all of them were written), in order.
pub fn commit_all(files: Vec<Staged>) -> Result<(), crate::Error> {
    for f in files {
        f.commit()?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn dir(name: &str) -> PathBuf {
        let d =
            std::env::temp_dir().join(format!("spherecal-output-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir_all(&d).unwrap();
        d
    }

    #[test]
    fn a_dropped_output_leaves_nothing_and_a_committed_one_is_whole() {
        let d = dir("staged");
        let p = d.join("a.bin");
        {
            let mut s = Staged::create(&p).unwrap();
            s.write_all(&[1u8; 5000]).unwrap();
            assert!(!p.exists(), "nothing under the final name while writing");
            assert!(partial_path(&p).exists());
        }
        assert!(
            !p.exists() && !partial_path(&p).exists(),
            "dropped: nothing left"
        );
        std::fs::write(&p, b"old").unwrap();
        let mut s = Staged::create(&p).unwrap();
        s.write_all(&[2u8; 5000]).unwrap();
        assert_eq!(
            std::fs::read(&p).unwrap(),
            b"old",
            "the old file stands until commit"
        );
        s.commit().unwrap();
        assert_eq!(std::fs::read(&p).unwrap(), vec![2u8; 5000]);
        assert!(!partial_path(&p).exists());
        assert!(pending().iter().all(|x| !x.starts_with(&d)));
        // Abandoned: writes are discarded, nothing is committed, nothing is left.
        let mut s = Staged::create(&d.join("b.bin")).unwrap();
        let h = s.abandon_handle();
        s.write_all(b"x").unwrap();
        h.abandon();
        s.write_all(b"y").unwrap();
        assert!(s.commit().unwrap_err().to_string().contains("abandoned"));
        assert!(!d.join("b.bin").exists() && !partial_path(&d.join("b.bin")).exists());
    }

    #[test]
    fn check_names_a_missing_folder_and_a_folder_given_as_a_file() {
        let d = dir("check");
        assert!(check("--las", &d.join("x.las")).is_ok());
        assert!(!partial_path(&d.join("x.las")).exists());
        let e = check("--las", &d.join("no/x.las")).unwrap_err().to_string();
        assert!(e.contains("does not exist"), "{e}");
        let e = check("--report", &d).unwrap_err().to_string();
        assert!(e.contains("is a folder"), "{e}");
    }
}
