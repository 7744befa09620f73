//! Output files that appear whole or not at all.
//!
//! Every file musculo writes goes first to a hidden temporary file in its destination folder
//! (`.<name>.tmp-<pid>-<n>`), is flushed to disk, and only then is renamed onto its name. A
//! rename within one folder is atomic: a reader — or the next run after a `kill -9` — finds
//! the old file or the new one, never part of one.
//!
//! A command that writes several files collects them in an [`OutputSet`]:
//! 1. [`OutputSet::add`] writes each file to its temporary name, creating missing folders;
//!    no file has its final name yet;
//! 2. [`OutputSet::commit`], once every file is written, records the renames in a journal
//!    (`.musculo-commit-<pid>-<n>`, in the first file's folder), renames every file and
//!    removes the journal;
//! 3. an `OutputSet` dropped without a commit (an error on the way) removes its temporaries.
//!
//! A run killed before step 2 leaves only hidden temporaries; one killed during the renames
//! (a few microseconds) leaves its journal as well. Both carry the process id, and once that
//! process is gone the next `OutputSet` writing into the folder removes the temporaries and
//! finishes a journaled commit (its files were complete and synced before the journal was
//! written), saying so in [`Committed::notes`]. Where the system has no `/proc` to tell a
//! live process from a dead one, stale files are left alone: hidden, and never taken for
//! outputs.
//!
//! Refused before anything is written ([`OutputSet::check`]): an output that is one of the
//! command's inputs (compared as canonical paths, so `a.mot`, `./a.mot` and a symbolic link
//! to it are one file), an output that is a folder, a device, a named pipe or a socket (the
//! rename would replace it), a path without a file name, and one file twice in a set. An
//! output that is a symbolic link replaces the file it points to and keeps the link. [`plain_name_problem`] says why a name taken from a setup file may not be
//! a file name inside a results folder; [`name_in_folder`] gives `-o out/` its meaning.
//!
//! Errors are [`Error::Output`] naming the output file (or the folder that could not be made).

use crate::error::Error;
use std::ffi::OsString;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

/// Marks the temporary name of a file being written: `.<name>.tmp-<pid>-<n>`.
const TEMPORARY_MARK: &str = ".tmp-";
/// Starts the name of a commit journal: `.musculo-commit-<pid>-<n>`.
const JOURNAL_PREFIX: &str = ".musculo-commit-";

fn output_error(path: &Path, message: impl Into<String>) -> Error {
    Error::Output {
        path: path.to_path_buf(),
        message: message.into(),
    }
}

/// A process-unique suffix `<pid>-<n>`.
fn unique_suffix() -> String {
    static COUNTER: AtomicU64 = AtomicU64::new(0);
    format!(
        "{}-{}",
        std::process::id(),
        COUNTER.fetch_add(1, Ordering::Relaxed)
    )
}

/// The folder of `path` (`.` for a bare file name).
fn folder_of(path: &Path) -> &Path {
    match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    }
}

/// A temporary file beside its target, renamed onto it by [`AtomicFile::rename`] and removed
/// if dropped before that.
pub(crate) struct AtomicFile {
    temp: PathBuf,
    target: PathBuf,
}

/// The file an output to `target` replaces: `target` itself when it is a regular file or does
/// not exist, the file a symbolic link points to (the link is kept, as a shell's `>` keeps
/// it). Anything else at that path — a device such as `/dev/null`, a named pipe, a socket, a
/// folder, a link to a missing file — is refused: renaming a new file onto it would replace
/// it (run as root, `-o /dev/null` would delete the device).
fn replaceable_target(target: &Path) -> crate::Result<PathBuf> {
    let Ok(meta) = std::fs::symlink_metadata(target) else {
        return Ok(target.to_path_buf());
    };
    let (resolved, meta) = if meta.file_type().is_symlink() {
        let resolved = target.canonicalize().map_err(|e| {
            output_error(
                target,
                format!("is a symbolic link to a file that cannot be reached ({e})"),
            )
        })?;
        let meta = std::fs::metadata(&resolved).map_err(|e| output_error(target, e.to_string()))?;
        (resolved, meta)
    } else {
        (target.to_path_buf(), meta)
    };
    if meta.is_file() {
        Ok(resolved)
    } else {
        let what = if meta.is_dir() {
            "an existing folder"
        } else {
            "a device, named pipe or socket, not a regular file"
        };
        Err(output_error(
            target,
            format!("is {what}: outputs are written as regular files; choose another path"),
        ))
    }
}

impl AtomicFile {
    /// Creates the temporary file (never an existing one) for `target` (see
    /// [`replaceable_target`]: a link is followed, a device or pipe refused).
    pub(crate) fn create(target: &Path) -> crate::Result<(AtomicFile, std::fs::File)> {
        let target = &replaceable_target(target)?;
        let name = target
            .file_name()
            .ok_or_else(|| output_error(target, "not a file path"))?;
        let mut temp_name = OsString::from(".");
        temp_name.push(name);
        temp_name.push(TEMPORARY_MARK);
        temp_name.push(unique_suffix());
        let temp = target.with_file_name(temp_name);
        let file = std::fs::OpenOptions::new()
            .write(true)
            .create_new(true)
            .open(&temp)
            .map_err(|e| output_error(target, e.to_string()))?;
        let atomic = AtomicFile {
            temp,
            target: target.to_path_buf(),
        };
        Ok((atomic, file))
    }

    /// Flushes the file's data to disk (before any rename makes it visible).
    pub(crate) fn sync(&self, file: std::fs::File) -> crate::Result<()> {
        file.sync_all()
            .map_err(|e| output_error(&self.target, e.to_string()))
    }

    /// Gives the temporary file its final name.
    pub(crate) fn rename(mut self) -> crate::Result<()> {
        std::fs::rename(&self.temp, &self.target)
            .map_err(|e| output_error(&self.target, e.to_string()))?;
        self.temp = PathBuf::new();
        Ok(())
    }

    /// Syncs and renames.
    pub(crate) fn commit(self, file: std::fs::File) -> crate::Result<()> {
        self.sync(file)?;
        self.rename()
    }
}

impl Drop for AtomicFile {
    fn drop(&mut self) {
        if !self.temp.as_os_str().is_empty() {
            let _ = std::fs::remove_file(&self.temp);
        }
    }
}

/// Writes `bytes` to `path` atomically (a temporary file beside it, synced, then renamed): an
/// interrupted write leaves the old file or the new one, never part of one. The folder must
/// exist; for a command's outputs use an [`OutputSet`].
pub fn write_file_atomic(path: &Path, bytes: &[u8]) -> crate::Result<()> {
    let (atomic, mut file) = AtomicFile::create(path)?;
    file.write_all(bytes)
        .map_err(|e| output_error(path, e.to_string()))?;
    atomic.commit(file)
}

/// True for the name of a temporary file written here (`.<name>.tmp-<pid>-<n>`): left behind
/// only when a process is killed mid-write, and safe to delete once that process is gone.
pub fn is_temporary_name(name: &str) -> bool {
    name.starts_with('.') && name.contains(TEMPORARY_MARK)
}

/// For the name of a temporary file whose writing process has certainly ended: the name of
/// the file it was to become (`.walk.npz.tmp-77-0` → `walk.npz`). None for any other name, and
/// for a temporary whose writer may still be running (another process writing beside us, or a
/// system where that cannot be told): such a file must be left alone.
pub fn abandoned_temporary_target(name: &str) -> Option<&str> {
    if !is_temporary_name(name) || name.starts_with(JOURNAL_PREFIX) {
        return None;
    }
    let pid = writer_pid(name)?;
    if !process_has_ended(pid) {
        return None;
    }
    Some(&name[1..name.rfind(TEMPORARY_MARK)?])
}

/// The process id in a temporary file's or a journal's name.
fn writer_pid(name: &str) -> Option<u32> {
    let suffix = if let Some(rest) = name.strip_prefix(JOURNAL_PREFIX) {
        rest
    } else if is_temporary_name(name) {
        &name[name.rfind(TEMPORARY_MARK)? + TEMPORARY_MARK.len()..]
    } else {
        return None;
    };
    let (pid, serial) = suffix.split_once('-')?;
    serial.parse::<u64>().ok()?;
    pid.parse().ok()
}

/// True when process `pid` has certainly ended (Linux: no `/proc/<pid>`); false where that
/// cannot be told.
fn process_has_ended(pid: u32) -> bool {
    let proc = Path::new("/proc");
    pid != std::process::id() && proc.join("self").exists() && !proc.join(pid.to_string()).exists()
}

/// `name` as a file name inside a results folder, or why it cannot be one: a path separator
/// (`/`, `\`), `.` or `..` would put the file somewhere else.
pub fn plain_name_problem(name: &str) -> Option<&'static str> {
    if name.contains(['/', '\\']) {
        Some("contains a path separator, which would put the output outside its results folder")
    } else if name == ".." || name == "." {
        Some("is a folder reference, which would put the output outside its results folder")
    } else if name.contains('\0') {
        Some("contains a NUL character")
    } else {
        None
    }
}

/// `output` itself, or `output/<default_name>` when `output` ends in a path separator
/// (`-o out/walk/` names a folder; missing folders are created when the files are written).
pub fn name_in_folder(output: &Path, default_name: &str) -> PathBuf {
    let text = output.as_os_str().to_string_lossy();
    if text.ends_with(std::path::is_separator) {
        output.join(default_name)
    } else {
        output.to_path_buf()
    }
}

/// `prefix` + `suffix` as a path (`out/walk` + `_force.sto`).
pub fn with_suffix(prefix: &Path, suffix: &str) -> PathBuf {
    let mut s = prefix.as_os_str().to_os_string();
    s.push(suffix);
    PathBuf::from(s)
}

/// The canonical path `target` would have: itself (resolving links) when it exists, else its
/// canonical folder joined with its name; None while the folder does not exist.
fn canonical_target(target: &Path) -> Option<PathBuf> {
    if let Ok(c) = target.canonicalize() {
        return Some(c);
    }
    let name = target.file_name()?;
    folder_of(target).canonicalize().ok().map(|f| f.join(name))
}

/// What [`OutputSet::commit`] did.
#[derive(Debug, Default)]
pub struct Committed {
    /// The files written, as the caller named them, in the order added.
    pub files: Vec<PathBuf>,
    /// What was found and tidied in the destination folders: temporaries removed and journaled
    /// commits finished, left by runs that were killed.
    pub notes: Vec<String>,
}

struct Staged {
    file: AtomicFile,
    /// The path as the caller gave it.
    given: PathBuf,
    canonical: PathBuf,
}

/// The outputs of one command, written together (see the module documentation).
pub struct OutputSet {
    /// The command's inputs: canonical path and the path as given.
    inputs: Vec<(PathBuf, PathBuf)>,
    staged: Vec<Staged>,
    /// Canonical folders already searched for stale files.
    tidied: Vec<PathBuf>,
    notes: Vec<String>,
}

impl OutputSet {
    /// An empty set whose outputs may not be any of `inputs` (paths that do not exist are
    /// ignored: they cannot be overwritten).
    pub fn new<'a>(inputs: impl IntoIterator<Item = &'a Path>) -> OutputSet {
        let inputs = inputs
            .into_iter()
            .filter_map(|p| Some((p.canonicalize().ok()?, p.to_path_buf())))
            .collect();
        OutputSet {
            inputs,
            staged: Vec::new(),
            tidied: Vec::new(),
            notes: Vec::new(),
        }
    }

    /// Refuses `target` when it could not be an output of this set: no file name, a folder,
    /// one of the inputs, or already in the set. Commands call it before their work, so that
    /// a bad output path is reported at once; [`OutputSet::add`] calls it again.
    pub fn check(&self, target: &Path) -> crate::Result<()> {
        let name = target.file_name().filter(|_| {
            !target
                .as_os_str()
                .to_string_lossy()
                .ends_with(std::path::is_separator)
        });
        if name.is_none() {
            return Err(output_error(target, "not a file path (it names a folder)"));
        }
        replaceable_target(target)?;
        let Some(canonical) = canonical_target(target) else {
            return Ok(()); // its folder does not exist yet: not an input, not staged
        };
        if let Some((_, given)) = self.inputs.iter().find(|(c, _)| *c == canonical) {
            return Err(output_error(
                target,
                format!(
                    "it is an input of this command ({}): writing it would destroy the input; \
                     choose another output path",
                    given.display()
                ),
            ));
        }
        if self.staged.iter().any(|s| s.canonical == canonical) {
            return Err(output_error(
                target,
                "this command would write this file twice",
            ));
        }
        Ok(())
    }

    /// Writes `bytes` to a temporary file beside `target` (creating missing folders); the
    /// file gets its name at [`OutputSet::commit`].
    pub fn add(&mut self, target: &Path, bytes: &[u8]) -> crate::Result<()> {
        self.check(target)?;
        let folder = folder_of(target);
        std::fs::create_dir_all(folder).map_err(|e| {
            output_error(
                target,
                format!("cannot create its folder {}: {e}", folder.display()),
            )
        })?;
        let canonical_folder = folder
            .canonicalize()
            .map_err(|e| output_error(target, e.to_string()))?;
        if !self.tidied.contains(&canonical_folder) {
            tidy_folder(&canonical_folder, &mut self.notes);
            self.tidied.push(canonical_folder.clone());
        }
        // The folder exists now: links and `..` inside it are resolved, so check again.
        self.check(target)?;
        let canonical = canonical_folder.join(target.file_name().unwrap_or_default());
        let (file, mut handle) = AtomicFile::create(&canonical)?;
        let shown = |e: std::io::Error| output_error(target, e.to_string());
        let mut writer = std::io::BufWriter::new(&mut handle);
        writer.write_all(bytes).map_err(shown)?;
        writer.flush().map_err(shown)?;
        drop(writer);
        file.sync(handle)?;
        self.staged.push(Staged {
            file,
            given: target.to_path_buf(),
            canonical,
        });
        Ok(())
    }

    /// The files added so far, as the caller named them.
    pub fn files(&self) -> impl Iterator<Item = &Path> {
        self.staged.iter().map(|s| s.given.as_path())
    }

    /// Renames every file onto its name (see the module documentation).
    pub fn commit(mut self) -> crate::Result<Committed> {
        let staged = std::mem::take(&mut self.staged);
        let journal = match staged.as_slice() {
            [] | [_] => None,
            [first, ..] => Some(write_journal(folder_of(&first.canonical), &staged)?),
        };
        let mut files = Vec::with_capacity(staged.len());
        let mut result = Ok(());
        for s in staged {
            if result.is_err() {
                break; // the rest are dropped: their temporaries removed
            }
            match s.file.rename() {
                Ok(()) => files.push(s.given),
                Err(e) => result = Err(e),
            }
        }
        if let Some(j) = journal {
            let _ = std::fs::remove_file(j);
        }
        match result {
            Ok(()) => Ok(Committed {
                files,
                notes: std::mem::take(&mut self.notes),
            }),
            Err(Error::Output { path, message }) if !files.is_empty() => Err(Error::Output {
                path,
                message: format!(
                    "{message} (after {} of this command's files were written: {})",
                    files.len(),
                    files
                        .iter()
                        .map(|f| f.display().to_string())
                        .collect::<Vec<_>>()
                        .join(", ")
                ),
            }),
            Err(e) => Err(e),
        }
    }
}

/// The journal of a commit: one `temporary<TAB>target` line per file (absolute paths), written
/// atomically into `folder`.
fn write_journal(folder: &Path, staged: &[Staged]) -> crate::Result<PathBuf> {
    let mut text = String::new();
    for s in staged {
        text.push_str(&s.file.temp.to_string_lossy());
        text.push('\t');
        text.push_str(&s.file.target.to_string_lossy());
        text.push('\n');
    }
    let path = folder.join(format!("{JOURNAL_PREFIX}{}", unique_suffix()));
    write_file_atomic(&path, text.as_bytes())?;
    Ok(path)
}

/// Finishes the journaled commits and removes the temporaries that ended processes left in
/// `folder`, noting each. Best effort: what cannot be tidied is left (it is hidden).
fn tidy_folder(folder: &Path, notes: &mut Vec<String>) {
    let Ok(entries) = std::fs::read_dir(folder) else {
        return;
    };
    let mut journals = Vec::new();
    let mut temporaries = Vec::new();
    for entry in entries.flatten() {
        let name = entry.file_name().to_string_lossy().into_owned();
        let Some(pid) = writer_pid(&name) else {
            continue;
        };
        if !process_has_ended(pid) {
            continue;
        }
        if name.starts_with(JOURNAL_PREFIX) {
            journals.push((pid, entry.path()));
        } else {
            temporaries.push((pid, entry.path()));
        }
    }
    // Journals first: their temporaries are complete files waiting for their names.
    for (pid, journal) in journals {
        let Ok(text) = std::fs::read_to_string(&journal) else {
            continue;
        };
        let mut finished = Vec::new();
        for line in text.lines() {
            let Some((temp, target)) = line.split_once('\t') else {
                continue;
            };
            if Path::new(temp).exists() && std::fs::rename(temp, target).is_ok() {
                finished.push(target.to_string());
            }
        }
        let _ = std::fs::remove_file(&journal);
        if !finished.is_empty() {
            notes.push(format!(
                "an interrupted run (process {pid}) had written {} file(s) but not yet named them \
                 all; named now: {}",
                finished.len(),
                finished.join(", ")
            ));
        }
    }
    let mut removed: Vec<(u32, usize)> = Vec::new();
    for (pid, temp) in temporaries {
        if temp.exists() && std::fs::remove_file(&temp).is_ok() {
            match removed.iter_mut().find(|(p, _)| *p == pid) {
                Some((_, n)) => *n += 1,
                None => removed.push((pid, 1)),
            }
        }
    }
    for (pid, n) in removed {
        notes.push(format!(
            "removed {n} unfinished temporary file(s) of an interrupted run (process {pid}) from {}",
            folder.display()
        ));
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    struct Dir(PathBuf);

    impl Dir {
        fn new(tag: &str) -> Dir {
            let d =
                std::env::temp_dir().join(format!("musculo-output-{tag}-{}", std::process::id()));
            let _ = std::fs::remove_dir_all(&d);
            std::fs::create_dir_all(&d).unwrap();
            Dir(d)
        }

        fn names(&self) -> Vec<String> {
            let mut v: Vec<String> = std::fs::read_dir(&self.0)
                .unwrap()
                .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
                .collect();
            v.sort();
            v
        }
    }

    impl Drop for Dir {
        fn drop(&mut self) {
            let _ = std::fs::remove_dir_all(&self.0);
        }
    }

    #[test]
    fn nothing_has_its_name_before_commit_and_everything_after() {
        let d = Dir::new("commit");
        let mut set = OutputSet::new([]);
        set.add(&d.0.join("a.sto"), b"a").unwrap();
        set.add(&d.0.join("sub/b.sto"), b"bb").unwrap();
        let names = d.names();
        assert!(!names.contains(&"a.sto".to_string()), "{names:?}");
        assert!(names.iter().any(|n| is_temporary_name(n)), "{names:?}");
        let done = set.commit().unwrap();
        assert_eq!(done.files, vec![d.0.join("a.sto"), d.0.join("sub/b.sto")]);
        assert_eq!(d.names(), vec!["a.sto", "sub"]);
        assert_eq!(std::fs::read(d.0.join("sub/b.sto")).unwrap(), b"bb");
        assert!(done.notes.is_empty());
    }

    #[test]
    fn a_set_dropped_without_commit_leaves_nothing() {
        let d = Dir::new("drop");
        let mut set = OutputSet::new([]);
        set.add(&d.0.join("a.sto"), b"a").unwrap();
        set.add(&d.0.join("b.sto"), b"b").unwrap();
        drop(set);
        assert!(d.names().is_empty(), "{:?}", d.names());
    }

    #[test]
    fn an_output_that_is_an_input_is_refused_however_it_is_spelled() {
        let d = Dir::new("input");
        let input = d.0.join("walk.mot");
        std::fs::write(&input, "data").unwrap();
        let set = OutputSet::new([input.as_path()]);
        for spelling in [
            input.clone(),
            d.0.join("./walk.mot"),
            d.0.join("sub/../walk.mot"),
        ] {
            if spelling.to_string_lossy().contains("sub/") {
                std::fs::create_dir_all(d.0.join("sub")).unwrap();
            }
            let e = set.check(&spelling).unwrap_err().to_string();
            assert!(e.contains("it is an input of this command"), "{e}");
        }
        #[cfg(unix)]
        {
            let link = d.0.join("link.mot");
            std::os::unix::fs::symlink(&input, &link).unwrap();
            assert!(set.check(&link).is_err());
        }
        assert_eq!(std::fs::read_to_string(&input).unwrap(), "data");
        assert!(set.check(&d.0.join("other.mot")).is_ok());
    }

    #[test]
    fn a_folder_and_a_repeated_file_are_refused() {
        let d = Dir::new("folder");
        let mut set = OutputSet::new([]);
        let e = set.check(&d.0).unwrap_err().to_string();
        assert!(e.contains("existing folder"), "{e}");
        set.add(&d.0.join("a"), b"1").unwrap();
        let e = set.add(&d.0.join("a"), b"2").unwrap_err().to_string();
        assert!(e.contains("twice"), "{e}");
    }

    #[test]
    fn a_trailing_separator_names_a_folder() {
        assert_eq!(
            name_in_folder(Path::new("out/walk/"), "x.sto"),
            Path::new("out/walk/x.sto")
        );
        assert_eq!(
            name_in_folder(Path::new("out/walk"), "x.sto"),
            Path::new("out/walk")
        );
        assert_eq!(
            with_suffix(Path::new("out/walk"), "_force.sto"),
            Path::new("out/walk_force.sto")
        );
    }

    #[test]
    fn names_that_leave_their_folder_are_refused() {
        for bad in ["../../x", "a/b", "a\\b", "..", "."] {
            assert!(plain_name_problem(bad).is_some(), "{bad}");
        }
        for good in ["walk", "subject01_walk..v2", "so.results"] {
            assert!(plain_name_problem(good).is_none(), "{good}");
        }
    }

    #[test]
    fn stale_files_of_an_ended_process_are_tidied_and_a_journal_is_finished() {
        if !Path::new("/proc/self").exists() {
            return; // process ids cannot be checked here; stale files are left alone
        }
        let d = Dir::new("stale");
        // A process id that has ended: a child that has been waited for.
        let mut child = std::process::Command::new("true").spawn().unwrap();
        child.wait().unwrap();
        let dead = child.id();
        // Killed while writing: a temporary only.
        std::fs::write(d.0.join(format!(".x.sto.tmp-{dead}-0")), "half").unwrap();
        // Killed during the renames: one file named, one waiting, the journal.
        let waiting = d.0.join(format!(".b.sto.tmp-{dead}-2"));
        std::fs::write(&waiting, "B").unwrap();
        std::fs::write(d.0.join("a.sto"), "A").unwrap();
        std::fs::write(
            d.0.join(format!("{JOURNAL_PREFIX}{dead}-3")),
            format!(
                "{}\t{}\n{}\t{}\n",
                d.0.join(format!(".a.sto.tmp-{dead}-1")).display(),
                d.0.join("a.sto").display(),
                waiting.display(),
                d.0.join("b.sto").display()
            ),
        )
        .unwrap();
        // A live process's temporary (this one's) is left alone.
        let mine =
            d.0.join(format!(".y.sto.tmp-{}-999999", std::process::id()));
        std::fs::write(&mine, "live").unwrap();
        let mut set = OutputSet::new([]);
        set.add(&d.0.join("c.sto"), b"C").unwrap();
        let done = set.commit().unwrap();
        assert_eq!(done.notes.len(), 2, "{:?}", done.notes);
        assert!(done.notes[0].contains("b.sto"), "{:?}", done.notes);
        assert!(done.notes[1].contains("removed 1"), "{:?}", done.notes);
        let mine_name = mine.file_name().unwrap().to_string_lossy().into_owned();
        assert_eq!(
            d.names(),
            vec![mine_name, "a.sto".into(), "b.sto".into(), "c.sto".into()]
        );
        assert_eq!(std::fs::read_to_string(d.0.join("b.sto")).unwrap(), "B");
    }

    #[test]
    fn a_write_into_a_read_only_folder_fails_and_leaves_nothing() {
        let d = Dir::new("readonly");
        let ro = d.0.join("ro");
        std::fs::create_dir_all(&ro).unwrap();
        let mut perms = std::fs::metadata(&ro).unwrap().permissions();
        perms.set_readonly(true);
        std::fs::set_permissions(&ro, perms.clone()).unwrap();
        if std::fs::write(ro.join("probe"), "x").is_ok() {
            // running as root: permissions are not enforced
            let _ = std::fs::remove_file(ro.join("probe"));
        } else {
            let mut set = OutputSet::new([]);
            set.add(&d.0.join("ok.sto"), b"1").unwrap();
            let e = set.add(&ro.join("a.sto"), b"2").unwrap_err().to_string();
            assert!(
                e.contains("cannot write output") && e.contains("a.sto"),
                "{e}"
            );
            drop(set);
            assert_eq!(d.names(), vec!["ro"]);
        }
        #[allow(clippy::permissions_set_readonly_false)]
        perms.set_readonly(false);
        std::fs::set_permissions(&ro, perms).unwrap();
    }

    #[test]
    fn writer_pids_are_read_from_temporary_and_journal_names() {
        assert_eq!(writer_pid(".a.sto.tmp-123-4"), Some(123));
        assert_eq!(writer_pid(".musculo-commit-77-0"), Some(77));
        assert_eq!(writer_pid("a.sto"), None);
        assert_eq!(writer_pid(".a.tmp-x-1"), None);
    }
}
