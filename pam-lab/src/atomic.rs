//! Atomic output: every file is written to a temporary file in the target's
//! directory and renamed over the target only when complete, so a failure
//! (bad input found late, full disk, a crash) never leaves a half-written
//! output behind.

use std::io::Write;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result};

fn parent_dir(path: &Path) -> PathBuf {
    match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    }
}

/// Write `bytes` to `path` atomically.
pub fn write_bytes(path: &Path, bytes: &[u8]) -> Result<()> {
    write_with(path, |w| w.write_all(bytes).map_err(Into::into))
}

/// Create `path` atomically from what `fill` writes into a buffered writer.
pub fn write_with<F>(path: &Path, fill: F) -> Result<()>
where
    F: FnOnce(&mut dyn Write) -> Result<()>,
{
    let dir = parent_dir(path);
    let tmp = tempfile::Builder::new()
        .prefix(".pam-lab-")
        .tempfile_in(&dir)
        .with_context(|| format!("cannot create a temporary file in {}", dir.display()))?;
    {
        let mut w = std::io::BufWriter::new(tmp.as_file());
        fill(&mut w).with_context(|| format!("writing {}", path.display()))?;
        w.flush()
            .with_context(|| format!("writing {}", path.display()))?;
    }
    tmp.as_file()
        .sync_all()
        .with_context(|| format!("syncing {}", path.display()))?;
    tmp.persist(path)
        .with_context(|| format!("cannot rename the temporary file to {}", path.display()))?;
    Ok(())
}

/// Create `path` atomically with a tool that insists on writing to a path
/// itself (the plotting backend): `draw` gets a temporary path in the same
/// directory that keeps `path`'s extension (the backend picks the format
/// from it); on success it is renamed to `path`, on failure removed.
pub fn write_via_path<F>(path: &Path, draw: F) -> Result<()>
where
    F: FnOnce(&Path) -> Result<()>,
{
    let dir = parent_dir(path);
    let suffix = path
        .extension()
        .map(|e| format!(".{}", e.to_string_lossy()))
        .unwrap_or_default();
    let tmp = tempfile::Builder::new()
        .prefix(".pam-lab-")
        .suffix(&suffix)
        .tempfile_in(&dir)
        .with_context(|| format!("cannot create a temporary file in {}", dir.display()))?;
    draw(tmp.path()).with_context(|| format!("drawing {}", path.display()))?;
    tmp.persist(path)
        .with_context(|| format!("cannot rename the temporary file to {}", path.display()))?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_failed_write_leaves_neither_target_nor_temporary() {
        let dir = tempfile::tempdir().unwrap();
        let target = dir.path().join("out.json");
        let err = write_with(&target, |w| {
            w.write_all(b"half")?;
            anyhow::bail!("input went bad")
        });
        assert!(err.is_err());
        assert!(!target.exists());
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 0);
    }

    #[test]
    fn a_failed_write_keeps_the_previous_file() {
        let dir = tempfile::tempdir().unwrap();
        let target = dir.path().join("model.blob");
        write_bytes(&target, b"old").unwrap();
        let _ = write_with(&target, |_| anyhow::bail!("no"));
        assert_eq!(std::fs::read(&target).unwrap(), b"old");
        write_bytes(&target, b"new").unwrap();
        assert_eq!(std::fs::read(&target).unwrap(), b"new");
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
    }

    #[test]
    fn via_path_keeps_the_extension_and_cleans_up_on_failure() {
        let dir = tempfile::tempdir().unwrap();
        let target = dir.path().join("plot.png");
        write_via_path(&target, |p| {
            assert_eq!(p.extension().unwrap(), "png");
            std::fs::write(p, b"png")?;
            Ok(())
        })
        .unwrap();
        assert_eq!(std::fs::read(&target).unwrap(), b"png");
        let _ = write_via_path(&dir.path().join("b.png"), |p| {
            std::fs::write(p, b"partial")?;
            anyhow::bail!("drawing failed")
        });
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
    }
}
