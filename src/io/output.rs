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
//! (a few microseconds) leaves its journal as well. Both carry their writer's identity —
//! host, PID namespace and process id (see the `owner` module) — and once that writer has certainly ended
//! the next `OutputSet` writing into the folder removes the temporaries and finishes a
//! journaled commit (its files were complete and synced before the journal was written),
//! saying so in [`Committed::notes`]. A file whose writer cannot be shown to have ended is
//! left alone: hidden, and never taken for an output.
//!
//! ## Whose file is it, and has its writer ended?
//!
//! Output folders are shared: shards of one dataset on a Slurm array or a Kubernetes job
//! write into one folder on a network file system, from several hosts and PID namespaces,
//! where a process id means nothing outside its own namespace. So a temporary's name is
//! `.<name>.tmp-<host>-<pidns>-<pid>-<n>`:
//! - `<host>`: 8 hex digits hashing the host's identity — `/etc/machine-id` (else the
//!   kernel's boot id) and the host name — the same in every PID namespace of one host and
//!   different on another host; `00000000` where neither can be read (the writer's host is
//!   then unknown, and nothing is ever probed for it);
//! - `<pidns>`: the writer's PID namespace (the inode of `/proc/self/ns/pid`; 0 unknown);
//! - `<pid>`: its process id in that namespace, `<n>` a counter.
//!
//! A writer on this host, in this PID namespace, with a `/proc` that shows this namespace
//! (`/proc/self` is this process), has ended when `/proc/<pid>` is gone or the process is a
//! zombie (killed, not yet reaped: state `Z` or `X`). Any other writer — another host,
//! another namespace, an unknown host, a name written before identities existed — cannot
//! be probed, and is judged by its lease: a live writer sets the modification time of each
//! of its temporaries and journals to the present every [`LEASE_REFRESH`] (a background
//! thread), so a file not touched for [`LEASE_PERIOD`] belongs to a writer that has ended
//! (or been stopped that long). This assumes the hosts' clocks agree to within a few
//! minutes, as NTP keeps them; the file system needs no locks, so NFS and the like work.
//!
//! Refused before anything is written ([`OutputSet::check`]): an output that is one of the
//! command's inputs (compared as canonical paths, so `a.mot`, `./a.mot` and a symbolic link
//! to it are one file), an output that is a folder, a device, a named pipe or a socket (the
//! rename would replace it), a path without a file name, and one file twice in a set. An
//! output that is a symbolic link replaces the file it points to and keeps the link. [`plain_name_problem`] says why a name taken from a setup file may not be
//! a file name inside a results folder; [`name_in_folder`] gives `-o out/` its meaning.
//!
//! Errors are [`Error::Output`] naming the output file (or the folder that could not be made).

mod owner;

use crate::error::Error;
use std::ffi::OsString;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

/// Marks the temporary name of a file being written: `.<name>.tmp-<owner>-<n>`.
const TEMPORARY_MARK: &str = ".tmp-";
/// Starts the name of a commit journal: `.musculo-commit-<owner>-<n>`.
const JOURNAL_PREFIX: &str = ".musculo-commit-";

/// How often a running writer refreshes the lease (modification time) of its temporaries.
pub const LEASE_REFRESH: std::time::Duration = std::time::Duration::from_secs(60);
/// How long a temporary of a writer that cannot be probed (another host or PID namespace)
/// may go untouched before its writer is taken to have ended: 15 minutes.
pub const LEASE_PERIOD: std::time::Duration = std::time::Duration::from_secs(15 * 60);

fn output_error(path: &Path, message: impl Into<String>) -> Error {
    Error::Output {
        path: path.to_path_buf(),
        message: message.into(),
    }
}

/// A process-unique suffix `<host>-<pidns>-<pid>-<n>` ([`owner`]).
fn unique_suffix() -> String {
    static COUNTER: AtomicU64 = AtomicU64::new(0);
    format!(
        "{}-{}",
        owner::Owner::this_process().token(),
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
        owner::lease_taken(&temp);
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
        owner::lease_released(&self.temp);
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
            owner::lease_released(&self.temp);
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

/// True for the name of a temporary file written here (`.<name>.tmp-<owner>-<n>`): left
/// behind only when a process is killed mid-write, and safe to delete once that process has
/// ended.
pub fn is_temporary_name(name: &str) -> bool {
    name.starts_with('.') && name.contains(TEMPORARY_MARK)
}

/// For the temporary file `name` in `folder` whose writer has certainly ended (see the
/// module documentation): the name of the file it was to become (`.walk.npz.tmp-…` →
/// `walk.npz`). None for any other name, and for a temporary whose writer may still be
/// running (another process writing beside us, on this host or another, whose lease is
/// fresh): such a file must be left alone.
pub fn abandoned_temporary_target<'n>(folder: &Path, name: &'n str) -> Option<&'n str> {
    if !is_temporary_name(name) || name.starts_with(JOURNAL_PREFIX) {
        return None;
    }
    let owner = writer_of(name)?;
    if !owner.has_ended(&folder.join(name)) {
        return None;
    }
    Some(&name[1..name.rfind(TEMPORARY_MARK)?])
}

/// The writer part `<host>-<pidns>-<pid>` of the temporary names of process `pid` on this
/// host and in this PID namespace (see the module documentation).
pub fn writer_token(pid: u32) -> String {
    owner::Owner {
        pid,
        ..owner::Owner::this_process()
    }
    .token()
}

/// The writer named in a temporary file's or a journal's name.
fn writer_of(name: &str) -> Option<owner::Owner> {
    let suffix = if let Some(rest) = name.strip_prefix(JOURNAL_PREFIX) {
        rest
    } else if is_temporary_name(name) {
        &name[name.rfind(TEMPORARY_MARK)? + TEMPORARY_MARK.len()..]
    } else {
        return None;
    };
    let (token, serial) = suffix.rsplit_once('-')?;
    serial.parse::<u64>().ok()?;
    owner::Owner::parse(token)
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
    /// Whether to search each destination folder for stale files (see
    /// [`OutputSet::new_in_tidied_folders`]).
    tidy: bool,
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
            tidy: true,
            notes: Vec::new(),
        }
    }

    /// An empty set with no inputs that leaves the destination folders' stale files alone:
    /// for a caller that writes many sets into one folder and tidied it once before (`augment`
    /// writes each clip's files as a set; searching the folder for every clip would cost
    /// time quadratic in the clips).
    pub fn new_in_tidied_folders() -> OutputSet {
        OutputSet {
            tidy: false,
            ..OutputSet::new([])
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
        if self.tidy && !self.tidied.contains(&canonical_folder) {
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
            owner::lease_released(&j);
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
    owner::lease_taken(&path);
    Ok(path)
}

/// Finishes the journaled commits and removes the temporaries that ended writers left in
/// `folder`, noting each. Best effort: what cannot be tidied is left (it is hidden).
fn tidy_folder(folder: &Path, notes: &mut Vec<String>) {
    let Ok(entries) = std::fs::read_dir(folder) else {
        return;
    };
    let mut journals = Vec::new();
    let mut temporaries = Vec::new();
    for entry in entries.flatten() {
        let name = entry.file_name().to_string_lossy().into_owned();
        let Some(owner) = writer_of(&name) else {
            continue;
        };
        if !owner.has_ended(&entry.path()) {
            continue;
        }
        if name.starts_with(JOURNAL_PREFIX) {
            journals.push((owner, entry.path()));
        } else {
            temporaries.push((owner, entry.path()));
        }
    }
    // Journals first: their temporaries are complete files waiting for their names.
    for (owner, journal) in journals {
        let finished = finish_journal(&journal);
        if !finished.is_empty() {
            notes.push(format!(
                "an interrupted run ({owner}) had written {} file(s) but not yet named them \
                 all; named now: {}",
                finished.len(),
                finished.join(", ")
            ));
        }
    }
    let mut removed: Vec<(String, usize)> = Vec::new();
    for (owner, temp) in temporaries {
        if temp.exists() && std::fs::remove_file(&temp).is_ok() {
            let owner = owner.to_string();
            match removed.iter_mut().find(|(p, _)| *p == owner) {
                Some((_, n)) => *n += 1,
                None => removed.push((owner, 1)),
            }
        }
    }
    for (owner, n) in removed {
        notes.push(format!(
            "removed {n} unfinished temporary file(s) of an interrupted run ({owner}) from {}",
            folder.display()
        ));
    }
}

/// True for a name a commit journal has (`.musculo-commit-<owner>-<n>`), whoever wrote it.
pub fn is_journal_name(name: &str) -> bool {
    name.starts_with(JOURNAL_PREFIX)
}

/// True for the name of a commit journal whose writer has certainly ended.
pub(crate) fn is_abandoned_journal(folder: &Path, name: &str) -> bool {
    name.starts_with(JOURNAL_PREFIX)
        && writer_of(name).is_some_and(|o| o.has_ended(&folder.join(name)))
}

/// Gives the files of an ended writer's journal their names (each file listed whose
/// temporary is still there) and removes the journal; returns the names given.
pub(crate) fn finish_journal(journal: &Path) -> Vec<String> {
    let Ok(text) = std::fs::read_to_string(journal) else {
        return Vec::new();
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
    let _ = std::fs::remove_file(journal);
    finished
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
        if std::fs::read_link("/proc/self").ok()
            != Some(PathBuf::from(std::process::id().to_string()))
        {
            return; // process ids cannot be checked here; stale files are left alone
        }
        let d = Dir::new("stale");
        // A process id that has ended: a child that has been waited for.
        let mut child = std::process::Command::new("true").spawn().unwrap();
        child.wait().unwrap();
        let dead = writer_token(child.id());
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
        let mine = d.0.join(format!(
            ".y.sto.tmp-{}-999999",
            writer_token(std::process::id())
        ));
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
    fn a_temporary_of_a_writer_that_cannot_be_probed_is_kept_until_its_lease_runs_out() {
        let d = Dir::new("lease");
        // A process id no process here has: on another host, or in another PID namespace
        // (where it may well be running), or in a name without a host — none can be probed.
        let absent = u32::MAX - 7;
        let me = owner::Owner::this_process();
        let other_host = owner::Owner {
            host: Some(me.host.unwrap_or(1) ^ 0x5a5a_5a5a),
            pid: absent,
            ..me
        };
        let other_namespace = owner::Owner {
            pid_namespace: me.pid_namespace + 1,
            pid: absent,
            ..me
        };
        let names = [
            format!(".a.npz.tmp-{}-0", other_host.token()),
            format!(".b.npz.tmp-{}-0", other_namespace.token()),
            format!(".c.npz.tmp-{absent}-0"),
            format!("{JOURNAL_PREFIX}{}-1", other_host.token()),
        ];
        for n in &names {
            std::fs::write(d.0.join(n), "live").unwrap();
        }
        let mut set = OutputSet::new([]);
        set.add(&d.0.join("d.sto"), b"D").unwrap();
        let done = set.commit().unwrap();
        assert!(done.notes.is_empty(), "{:?}", done.notes);
        for n in &names {
            assert!(d.0.join(n).exists(), "{n} removed while its lease is fresh");
            assert!(abandoned_temporary_target(&d.0, n).is_none(), "{n}");
        }
        // Untouched for longer than the lease period: their writers have ended.
        let old = std::time::SystemTime::now() - LEASE_PERIOD - std::time::Duration::from_secs(60);
        for n in &names {
            let f = std::fs::OpenOptions::new()
                .write(true)
                .open(d.0.join(n))
                .unwrap();
            f.set_modified(old).unwrap();
        }
        assert_eq!(abandoned_temporary_target(&d.0, &names[0]), Some("a.npz"));
        let mut set = OutputSet::new([]);
        set.add(&d.0.join("e.sto"), b"E").unwrap();
        let done = set.commit().unwrap();
        assert_eq!(d.names(), vec!["d.sto", "e.sto"], "{:?}", done.notes);
    }

    #[test]
    fn a_temporary_of_a_killed_writer_not_yet_reaped_is_removed() {
        if std::fs::read_link("/proc/self").ok()
            != Some(PathBuf::from(std::process::id().to_string()))
        {
            return;
        }
        let d = Dir::new("zombie");
        let mut child = std::process::Command::new("sleep")
            .arg("30")
            .spawn()
            .unwrap();
        let name = format!(".z.npz.tmp-{}-0", writer_token(child.id()));
        std::fs::write(d.0.join(&name), "half").unwrap();
        assert!(abandoned_temporary_target(&d.0, &name).is_none(), "alive");
        child.kill().unwrap();
        let deadline = std::time::Instant::now() + std::time::Duration::from_secs(5);
        while abandoned_temporary_target(&d.0, &name).is_none()
            && std::time::Instant::now() < deadline
        {
            std::thread::sleep(std::time::Duration::from_millis(10));
        }
        assert_eq!(abandoned_temporary_target(&d.0, &name), Some("z.npz"));
        child.wait().unwrap();
    }

    #[test]
    fn writers_are_read_from_temporary_and_journal_names() {
        let me = owner::Owner::this_process();
        let w = writer_of(&format!(".a.sto.tmp-{}-4", me.token())).unwrap();
        assert_eq!(w, me);
        assert_eq!(writer_of(".musculo-commit-77-0").map(|o| o.pid), Some(77));
        assert_eq!(writer_of(".a.sto.tmp-123-4").map(|o| o.host), Some(None));
        assert!(writer_of("a.sto").is_none());
        assert!(writer_of(".a.tmp-x-1").is_none());
    }
}
