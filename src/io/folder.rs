//! The files below a folder, for commands that take folders of clips (`augment`,
//! `evaluate`, `report`).

use crate::error::Error;
use std::path::{Path, PathBuf};

/// Every file below `root`, recursively, following links to folders; entries whose names
/// start with `.` are left out when `skip_hidden` (an augmentation's `.musculo/`). The order
/// is the file system's: callers sort what they keep.
///
/// A link back to a folder being walked (`sub/up -> ..`) would repeat the tree without end —
/// it made 41 copies of a clip, `sub/up/sub/up/…`, until the path length ran out — and is an
/// error naming the link and the folder it leads to.
pub fn files_below(root: &Path, skip_hidden: bool) -> crate::Result<Vec<PathBuf>> {
    let mut out = Vec::new();
    let mut open = vec![canonical(root)?];
    walk(root, skip_hidden, &mut out, &mut open)?;
    Ok(out)
}

fn canonical(path: &Path) -> crate::Result<PathBuf> {
    std::fs::canonicalize(path).map_err(|source| Error::Io {
        path: path.to_path_buf(),
        source,
    })
}

/// `open`: the folders being walked, resolved (the root and the path down to `dir`).
fn walk(
    dir: &Path,
    skip_hidden: bool,
    out: &mut Vec<PathBuf>,
    open: &mut Vec<PathBuf>,
) -> crate::Result<()> {
    let entries = std::fs::read_dir(dir).map_err(|source| Error::Io {
        path: dir.to_path_buf(),
        source,
    })?;
    for entry in entries {
        let entry = entry.map_err(|source| Error::Io {
            path: dir.to_path_buf(),
            source,
        })?;
        if skip_hidden && entry.file_name().to_string_lossy().starts_with('.') {
            continue;
        }
        let path = entry.path();
        if path.is_dir() {
            let resolved = canonical(&path)?;
            if let Some(ancestor) = open.iter().find(|a| **a == resolved) {
                return Err(Error::invalid(
                    "--input",
                    format!(
                        "{} leads back to {}, a folder it is in: the tree would repeat without \
                         end (remove the link, or give the folders as separate inputs)",
                        path.display(),
                        ancestor.display()
                    ),
                ));
            }
            open.push(resolved);
            walk(&path, skip_hidden, out, open)?;
            open.pop();
        } else {
            out.push(path);
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn files_are_found_below_links_and_a_loop_is_an_error() {
        let root = std::env::temp_dir().join(format!("musculo-folder-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&root);
        std::fs::create_dir_all(root.join("a/b")).unwrap();
        std::fs::create_dir_all(root.join("elsewhere")).unwrap();
        std::fs::write(root.join("a/b/clip.npy"), b"").unwrap();
        std::fs::write(root.join("a/.hidden"), b"").unwrap();
        std::fs::write(root.join("elsewhere/other.npy"), b"").unwrap();
        std::os::unix::fs::symlink(root.join("elsewhere"), root.join("a/linked")).unwrap();
        let names = |skip| {
            let mut v: Vec<String> = files_below(&root.join("a"), skip)
                .unwrap()
                .iter()
                .map(|p| {
                    let rel = p.strip_prefix(root.join("a")).unwrap();
                    rel.to_string_lossy().into_owned()
                })
                .collect();
            v.sort();
            v
        };
        assert_eq!(names(true), ["b/clip.npy", "linked/other.npy"]);
        assert_eq!(names(false), [".hidden", "b/clip.npy", "linked/other.npy"]);
        // a link to a folder above: an error naming it, not 41 nested copies
        std::os::unix::fs::symlink(root.join("a"), root.join("a/b/up")).unwrap();
        let e = files_below(&root.join("a"), true).unwrap_err().to_string();
        assert!(
            e.contains("b/up leads back to") && e.contains("repeat"),
            "{e}"
        );
        let _ = std::fs::remove_dir_all(&root);
    }
}
