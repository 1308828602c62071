//! The real brain meshes fissure ships in `assets/brain/` (origin and licence
//! in its `NOTICE.md`): the coarse mesh (25.8k nodes) and the fine one (q15,
//! 62.8k nodes), gzip'd Gmsh files the mesh loader reads directly.
//!
//! In: nothing, or a folder a user names (`fissure bench collision
//! --mesh-dir`). Out: the paths of the two meshes. Stays true: the shipped
//! folder is the source tree's own (`CARGO_MANIFEST_DIR/assets/brain`), so the
//! study's brain preset, the benches and the tests read the same files in any
//! clone; a folder a user names may hold them plain (`.msh`) or gzip'd.

use std::path::{Path, PathBuf};

/// File stem of the coarse real brain.
pub const COARSE: &str = "brain_pial_coarse";
/// File stem of the fine real brain.
pub const FINE: &str = "brain_pial_q15";

/// The folder of the shipped meshes.
pub fn shipped_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/brain")
}

/// The shipped mesh `stem` (`COARSE` or `FINE`).
pub fn shipped(stem: &str) -> PathBuf {
    shipped_dir().join(format!("{stem}.msh.gz"))
}

/// The mesh `stem` in `dir`: `stem.msh.gz`, else `stem.msh`; `None` when neither is there.
pub fn find_in(dir: &Path, stem: &str) -> Option<PathBuf> {
    [format!("{stem}.msh.gz"), format!("{stem}.msh")].into_iter().map(|name| dir.join(name)).find(|p| p.is_file())
}

/// A mesh file's name for tables and reports: its file name without the
/// format extension and a trailing `.gz` (`brain_pial_q15.msh.gz` -> `brain_pial_q15`).
pub fn label(path: &Path) -> String {
    let name = path.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
    let name = name.strip_suffix(".gz").or_else(|| name.strip_suffix(".GZ")).unwrap_or(&name);
    match name.rsplit_once('.') {
        Some((stem, _)) if !stem.is_empty() => stem.to_string(),
        _ => name.to_string(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_shipped_meshes_are_in_the_tree() {
        for stem in [COARSE, FINE] {
            assert!(shipped(stem).is_file(), "{} is missing", shipped(stem).display());
            assert_eq!(find_in(&shipped_dir(), stem), Some(shipped(stem)));
        }
        assert_eq!(find_in(&shipped_dir(), "no_such_brain"), None);
    }

    #[test]
    fn labels_drop_the_format_and_compression() {
        assert_eq!(label(Path::new("a/brain_pial_q15.msh.gz")), "brain_pial_q15");
        assert_eq!(label(Path::new("brain_pial_coarse.msh")), "brain_pial_coarse");
        assert_eq!(label(Path::new("x.vtu")), "x");
        assert_eq!(label(Path::new("noext")), "noext");
    }
}
