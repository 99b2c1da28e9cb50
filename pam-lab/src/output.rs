//! One atomic output set per command: either every file a command writes
//! appears, or none does.
//!
//! Files are staged in a temporary directory created next to their targets
//! (the same file system, so the final step is a rename, not a copy). Nothing
//! touches a target until [`OutputSet::commit`]: it checks every target
//! first (a directory in the way, a read-only file, a missing parent), then
//! renames the staged files over their targets one by one. Should a rename
//! fail half-way (the disk vanished), the targets already renamed are put
//! back as they were (the previous file restored, a new one removed). A set
//! dropped without `commit` — an error anywhere in the command — removes its
//! staging directory and leaves the targets untouched.
//!
//! Every error names the path it is about. Files get the ordinary
//! permissions a new file gets (`0644` under the usual umask), not the
//! `0600` of a temporary file.

use std::fmt;
use std::io::Write;
use std::path::{Path, PathBuf};

/// An output error, always naming its path.
#[derive(Debug)]
pub struct OutputError {
    /// The path the error is about.
    pub path: PathBuf,
    /// What was being done.
    pub action: &'static str,
    /// The cause.
    pub cause: String,
}

impl fmt::Display for OutputError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "{}: {}: {}",
            self.path.display(),
            self.action,
            self.cause
        )
    }
}

impl std::error::Error for OutputError {}

fn out_err(path: &Path, action: &'static str, cause: impl fmt::Display) -> OutputError {
    OutputError {
        path: path.to_path_buf(),
        action,
        cause: cause.to_string(),
    }
}

/// Staging directories alive in this process, for [`remove_staging_on_interrupt`].
static STAGING: std::sync::Mutex<Vec<PathBuf>> = std::sync::Mutex::new(Vec::new());
/// Held by [`OutputSet::commit`] while it moves files into place: an
/// interrupt waits for it, so a set is never left half moved (and its
/// backups, in the staging directory, are not removed under it).
static COMMITTING: std::sync::Mutex<()> = std::sync::Mutex::new(());
/// Whether a set of this process was committed (the interrupt's message).
static COMMITTED: std::sync::atomic::AtomicBool = std::sync::atomic::AtomicBool::new(false);

/// On SIGINT or SIGTERM (Ctrl-C during a long `diagnose`), remove every
/// staging directory of this process and exit with code 130: an interrupted
/// command leaves nothing behind, as a failed one does. Call once, at start.
pub fn remove_staging_on_interrupt() -> Result<(), OutputError> {
    ctrlc::set_handler(|| {
        // A commit under way finishes (or rolls back) first.
        let _commit = COMMITTING.lock();
        if let Ok(dirs) = STAGING.lock() {
            for d in dirs.iter() {
                let _ = std::fs::remove_dir_all(d);
            }
        }
        let what = if COMMITTED.load(std::sync::atomic::Ordering::SeqCst) {
            "interrupted after the outputs were written"
        } else {
            "interrupted: nothing written"
        };
        let _ = writeln!(std::io::stderr(), "{what}");
        std::process::exit(130);
    })
    .map_err(|e| out_err(Path::new("."), "cannot watch for Ctrl-C", e))
}

fn register_staging(dir: &Path, alive: bool) {
    if let Ok(mut dirs) = STAGING.lock() {
        if alive {
            dirs.push(dir.to_path_buf());
        } else {
            dirs.retain(|d| d != dir);
        }
    }
}

/// Where a target's staging directory goes: its parent, or `.`.
fn parent_dir(path: &Path) -> PathBuf {
    match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    }
}

/// A set of output files staged for an all-or-nothing commit.
#[derive(Debug)]
pub struct OutputSet {
    /// The command's input files ([`OutputSet::protect`]), as
    /// `(path given, identity)`: no target may be one of them.
    inputs: Vec<(PathBuf, FileId)>,
    /// Staging directories, one per target directory (usually one).
    stages: Vec<(PathBuf, tempfile::TempDir)>,
    /// `(staged file, target)` in the order added.
    files: Vec<(PathBuf, PathBuf)>,
    /// Directories the set creates on commit (the `-o DIR` of fit and
    /// diagnose), outermost first.
    dirs: Vec<PathBuf>,
}

impl OutputSet {
    /// An empty set; nothing is created until a file is added.
    pub fn new() -> OutputSet {
        OutputSet {
            inputs: Vec::new(),
            stages: Vec::new(),
            files: Vec::new(),
            dirs: Vec::new(),
        }
    }

    /// Files will go into `dir`, created on commit if missing. Checked now:
    /// `dir` must be a directory or not exist, and its nearest existing
    /// ancestor must be a directory.
    pub fn into_dir(&mut self, dir: &Path) -> Result<(), OutputError> {
        match std::fs::metadata(dir) {
            Ok(m) if m.is_dir() => return self.stage_for(&dir.join("x")).map(|_| ()),
            Ok(_) => return Err(out_err(dir, "cannot write into it", "not a directory")),
            Err(e) if e.kind() != std::io::ErrorKind::NotFound => {
                // A file where a directory should be, further up?
                for a in dir
                    .ancestors()
                    .skip(1)
                    .filter(|a| !a.as_os_str().is_empty())
                {
                    if a.is_file() {
                        return Err(out_err(
                            a,
                            "cannot create the output directory below it",
                            "not a directory",
                        ));
                    }
                }
                return Err(out_err(dir, "cannot use as the output directory", e));
            }
            Err(_) => {}
        }
        // Missing: the outermost missing ancestors are created on commit.
        let mut missing = vec![dir.to_path_buf()];
        let mut p = dir.to_path_buf();
        while let Some(parent) = p.parent().filter(|q| !q.as_os_str().is_empty()) {
            match std::fs::metadata(parent) {
                Ok(m) if m.is_dir() => break,
                Ok(_) => {
                    return Err(out_err(
                        parent,
                        "cannot create the output directory below it",
                        "not a directory",
                    ))
                }
                Err(_) => missing.push(parent.to_path_buf()),
            }
            p = parent.to_path_buf();
        }
        missing.reverse();
        for d in missing {
            if !self.dirs.contains(&d) {
                self.dirs.push(d);
            }
        }
        // The staging directory now: an unwritable place fails before the work.
        self.stage_for(&dir.join("x")).map(|_| ())
    }

    /// Never write over `input`: a target that is the same file (by path,
    /// through symbolic links, or a hard link to it) is refused. Call with
    /// every file the command reads, before its targets are checked.
    pub fn protect(&mut self, input: &Path) {
        if let Some(id) = file_id(input) {
            self.inputs.push((input.to_path_buf(), id));
        }
    }

    /// Whether `target` is one of the protected inputs.
    fn check_not_input(&self, target: &Path) -> Result<(), OutputError> {
        if let Some(id) = file_id(target) {
            if let Some((input, _)) = self.inputs.iter().find(|(_, i)| *i == id) {
                return Err(out_err(
                    target,
                    "cannot write",
                    format!(
                        "it is the input {} of this command (choose another output name)",
                        input.display()
                    ),
                ));
            }
        }
        Ok(())
    }

    /// [`OutputSet::check_target`] for each of `names` in `dir`, when `dir`
    /// exists already (a new one is empty).
    pub fn check_in_dir(&mut self, dir: &Path, names: &[&str]) -> Result<(), OutputError> {
        if dir.is_dir() {
            for n in names {
                self.check_target(&dir.join(n))?;
            }
        }
        Ok(())
    }

    /// Check now, before the work, that `target` can be written: not a
    /// directory, in an existing directory where files can be created.
    pub fn check_target(&mut self, target: &Path) -> Result<(), OutputError> {
        self.check_not_input(target)?;
        if target.is_dir() {
            return Err(out_err(target, "cannot write", "is a directory"));
        }
        let dir = parent_dir(target);
        match std::fs::metadata(&dir) {
            Ok(m) if m.is_dir() => {}
            Ok(_) => return Err(out_err(&dir, "cannot write into it", "not a directory")),
            Err(e) => return Err(out_err(&dir, "cannot write into it", e)),
        }
        if let Ok(m) = std::fs::metadata(target) {
            if m.permissions().readonly() {
                return Err(out_err(target, "cannot replace", "the file is read-only"));
            }
        }
        self.stage_for(target).map(|_| ())
    }

    /// The staging directory for `target`'s directory. A target whose
    /// directory does not exist yet (created on commit) is staged in the
    /// nearest existing ancestor.
    fn stage_for(&mut self, target: &Path) -> Result<PathBuf, OutputError> {
        let mut dir = parent_dir(target);
        while !dir.is_dir() {
            match dir.parent().filter(|q| !q.as_os_str().is_empty()) {
                Some(p) => dir = p.to_path_buf(),
                None => dir = PathBuf::from("."),
            }
            if dir == Path::new(".") {
                break;
            }
        }
        if let Some((_, t)) = self.stages.iter().find(|(d, _)| *d == dir) {
            return Ok(t.path().to_path_buf());
        }
        let t = tempfile::Builder::new()
            .prefix(".pam-lab-staging-")
            .tempdir_in(&dir)
            .map_err(|e| out_err(&dir, "cannot create a staging directory in it", e))?;
        let p = t.path().to_path_buf();
        register_staging(&p, true);
        self.stages.push((dir, t));
        Ok(p)
    }

    fn staged_path(&mut self, target: &Path) -> Result<PathBuf, OutputError> {
        if self.files.iter().any(|(_, t)| t == target) {
            return Err(out_err(
                target,
                "cannot write",
                "named twice in one command",
            ));
        }
        self.check_not_input(target)?;
        if target.is_dir() {
            return Err(out_err(target, "cannot write", "is a directory"));
        }
        let stage = self.stage_for(target)?;
        // Keep the extension: the plotting backend picks the format from it.
        let ext = target
            .extension()
            .map(|e| format!(".{}", e.to_string_lossy()))
            .unwrap_or_default();
        let staged = stage.join(format!("{}{ext}", self.files.len()));
        self.files.push((staged.clone(), target.to_path_buf()));
        Ok(staged)
    }

    /// Stage `bytes` for `target`.
    pub fn add_bytes(&mut self, target: &Path, bytes: &[u8]) -> Result<(), OutputError> {
        self.add_with(target, |w| w.write_all(bytes))
    }

    /// Stage what `fill` writes (buffered) for `target`.
    pub fn add_with<F>(&mut self, target: &Path, fill: F) -> Result<(), OutputError>
    where
        F: FnOnce(&mut dyn Write) -> std::io::Result<()>,
    {
        let staged = self.staged_path(target)?;
        let file =
            std::fs::File::create(&staged).map_err(|e| out_err(target, "cannot write", e))?;
        let mut w = std::io::BufWriter::new(file);
        fill(&mut w).map_err(|e| out_err(target, "cannot write", e))?;
        w.flush().map_err(|e| out_err(target, "cannot write", e))?;
        Ok(())
    }

    /// Stage a file written by a tool that insists on a path of its own
    /// (the plotting backend): `draw` gets a staging path with `target`'s
    /// extension.
    pub fn add_via_path<F>(&mut self, target: &Path, draw: F) -> anyhow::Result<()>
    where
        F: FnOnce(&Path) -> anyhow::Result<()>,
    {
        let staged = self.staged_path(target)?;
        draw(&staged).map_err(|e| out_err(target, "cannot draw", format!("{e:#}")))?;
        if !staged.is_file() {
            return Err(
                out_err(target, "cannot draw", "the plotting backend wrote nothing").into(),
            );
        }
        Ok(())
    }

    /// The targets, in the order added.
    pub fn targets(&self) -> Vec<PathBuf> {
        self.files.iter().map(|(_, t)| t.clone()).collect()
    }

    /// Check every target, then move every staged file into place. On an
    /// error nothing is left changed.
    pub fn commit(mut self) -> Result<Vec<PathBuf>, OutputError> {
        // 1. Every target replaceable: not a directory, its directory writable.
        for (_, target) in &self.files {
            self.check_not_input(target)?;
            if let Ok(m) = std::fs::symlink_metadata(target) {
                if m.is_dir() {
                    return Err(out_err(target, "cannot replace", "is a directory"));
                }
            }
        }
        // An interrupt waits until every file is in place or put back.
        let _committing = COMMITTING.lock();
        // 2. Directories.
        let mut made_dirs = Vec::new();
        for d in &self.dirs {
            if d.is_dir() {
                continue;
            }
            if let Err(e) = std::fs::create_dir(d) {
                undo_dirs(&made_dirs);
                return Err(out_err(d, "cannot create the directory", e));
            }
            made_dirs.push(d.clone());
        }
        // 3. Ordinary permissions (the umask's), then rename; undo on failure.
        let mode = ordinary_mode();
        let mut done: Vec<(PathBuf, Option<PathBuf>)> = Vec::new();
        let backup_dir = self.stages.first().map(|(_, t)| t.path().to_path_buf());
        for (k, (staged, target)) in self.files.iter().enumerate() {
            if let Err(e) = set_mode(staged, mode) {
                rollback(&done);
                undo_dirs(&made_dirs);
                return Err(out_err(target, "cannot set permissions", e));
            }
            // Keep the previous file until the whole set is in place.
            let backup = match (&backup_dir, target.is_file()) {
                (Some(b), true) => {
                    let bk = b.join(format!("previous-{k}"));
                    match std::fs::hard_link(target, &bk) {
                        Ok(()) => Some(bk),
                        Err(_) => None,
                    }
                }
                _ => None,
            };
            if let Err(e) = std::fs::rename(staged, target) {
                rollback(&done);
                undo_dirs(&made_dirs);
                return Err(out_err(target, "cannot write", e));
            }
            done.push((target.clone(), backup));
        }
        let targets = self.targets();
        self.files.clear();
        COMMITTED.store(true, std::sync::atomic::Ordering::SeqCst);
        Ok(targets)
    }
}

impl Drop for OutputSet {
    fn drop(&mut self) {
        // Each staging directory is removed with its `TempDir`, then
        // forgotten by the interrupt handler (not before: an interrupt in
        // between still removes it).
        for (_, t) in std::mem::take(&mut self.stages) {
            let path = t.path().to_path_buf();
            drop(t);
            register_staging(&path, false);
        }
    }
}

impl Default for OutputSet {
    fn default() -> Self {
        OutputSet::new()
    }
}

/// What makes two paths one file.
#[derive(Clone, Debug, PartialEq, Eq)]
enum FileId {
    /// Device and inode (links of every kind agree).
    #[cfg(unix)]
    Inode(u64, u64),
    /// The canonical path, elsewhere.
    #[cfg(not(unix))]
    Canonical(PathBuf),
}

/// The identity of an existing file (following links); `None` when it
/// does not exist.
fn file_id(path: &Path) -> Option<FileId> {
    #[cfg(unix)]
    {
        use std::os::unix::fs::MetadataExt;
        std::fs::metadata(path)
            .ok()
            .map(|m| FileId::Inode(m.dev(), m.ino()))
    }
    #[cfg(not(unix))]
    {
        std::fs::canonicalize(path).ok().map(FileId::Canonical)
    }
}

/// Put targets back: restore a previous file, remove a new one.
fn rollback(done: &[(PathBuf, Option<PathBuf>)]) {
    for (target, backup) in done.iter().rev() {
        match backup {
            Some(b) => {
                let _ = std::fs::rename(b, target);
            }
            None => {
                let _ = std::fs::remove_file(target);
            }
        }
    }
}

fn undo_dirs(made: &[PathBuf]) {
    for d in made.iter().rev() {
        let _ = std::fs::remove_dir(d);
    }
}

#[cfg(unix)]
fn ordinary_mode() -> u32 {
    // The umask cannot be read without changing it; a new file created
    // the ordinary way shows it.
    let probe = tempfile::Builder::new()
        .prefix(".pam-lab-mode-")
        .tempdir()
        .ok()
        .and_then(|d| {
            let f = d.path().join("probe");
            std::fs::File::create(&f).ok()?;
            use std::os::unix::fs::PermissionsExt;
            std::fs::metadata(&f)
                .ok()
                .map(|m| m.permissions().mode() & 0o777)
        });
    probe.unwrap_or(0o644)
}

#[cfg(not(unix))]
fn ordinary_mode() -> u32 {
    0
}

#[cfg(unix)]
fn set_mode(path: &Path, mode: u32) -> std::io::Result<()> {
    use std::os::unix::fs::PermissionsExt;
    std::fs::set_permissions(path, std::fs::Permissions::from_mode(mode))
}

#[cfg(not(unix))]
fn set_mode(_path: &Path, _mode: u32) -> std::io::Result<()> {
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn entries(dir: &Path) -> Vec<String> {
        let mut v: Vec<String> = std::fs::read_dir(dir)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        v.sort();
        v
    }

    #[test]
    fn a_committed_set_writes_every_file_with_ordinary_permissions() {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("a/b");
        let mut set = OutputSet::new();
        set.into_dir(&out).unwrap();
        set.add_bytes(&out.join("x.json"), b"{}").unwrap();
        set.add_with(&out.join("y.csv"), |w| w.write_all(b"t\n"))
            .unwrap();
        set.add_via_path(&out.join("z.png"), |p| {
            assert_eq!(p.extension().unwrap(), "png");
            std::fs::write(p, b"png")?;
            Ok(())
        })
        .unwrap();
        assert!(!out.exists(), "nothing before the commit");
        let written = set.commit().unwrap();
        assert_eq!(written.len(), 3);
        assert_eq!(entries(&out), ["x.json", "y.csv", "z.png"]);
        assert_eq!(entries(dir.path()), ["a"]);
        #[cfg(unix)]
        {
            use std::os::unix::fs::PermissionsExt;
            let mode = std::fs::metadata(out.join("x.json"))
                .unwrap()
                .permissions()
                .mode();
            assert_eq!(mode & 0o777, ordinary_mode());
            assert_ne!(mode & 0o044, 0, "readable by others under a 022 umask");
        }
    }

    #[test]
    fn a_dropped_set_leaves_nothing_and_keeps_old_files() {
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(dir.path().join("old.csv"), b"old").unwrap();
        let mut set = OutputSet::new();
        set.add_bytes(&dir.path().join("old.csv"), b"new").unwrap();
        set.add_bytes(&dir.path().join("new.csv"), b"new").unwrap();
        let failed = set.add_via_path(&dir.path().join("p.png"), |_| anyhow::bail!("no font"));
        let msg = failed.unwrap_err().to_string();
        assert!(msg.contains("p.png") && msg.contains("no font"), "{msg}");
        drop(set);
        assert_eq!(entries(dir.path()), ["old.csv"]);
        assert_eq!(std::fs::read(dir.path().join("old.csv")).unwrap(), b"old");
    }

    #[test]
    fn a_failed_commit_restores_every_target() {
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(dir.path().join("a.csv"), b"old").unwrap();
        let mut set = OutputSet::new();
        set.add_bytes(&dir.path().join("a.csv"), b"new").unwrap();
        set.add_bytes(&dir.path().join("b.csv"), b"new").unwrap();
        // A directory appears where the second target goes.
        std::fs::create_dir(dir.path().join("b.csv")).unwrap();
        let e = set.commit().unwrap_err();
        assert!(e.to_string().contains("b.csv"), "{e}");
        assert_eq!(std::fs::read(dir.path().join("a.csv")).unwrap(), b"old");
        assert_eq!(entries(dir.path()), ["a.csv", "b.csv"]);
    }

    #[test]
    fn a_file_in_the_way_of_the_directory_is_named() {
        let dir = tempfile::tempdir().unwrap();
        let f = dir.path().join("f");
        std::fs::write(&f, b"").unwrap();
        let e = OutputSet::new().into_dir(&f.join("sub")).unwrap_err();
        assert!(e.to_string().starts_with(&f.display().to_string()), "{e}");
        let e = OutputSet::new().into_dir(&f).unwrap_err();
        assert!(e.to_string().contains("not a directory"), "{e}");
    }
}
