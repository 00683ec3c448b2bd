//! A temporary folder for test files (meshes, caches), removed on drop.

use std::path::PathBuf;

/// A folder under the system's temporary directory, named by `tag` and the process id.
pub struct TempDir(pub PathBuf);

impl TempDir {
    /// The folder `genplan-<tag>-<pid>`, created.
    pub fn new(tag: &str) -> TempDir {
        let dir = std::env::temp_dir().join(format!("genplan-{tag}-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        TempDir(dir)
    }

    /// Write `text` to the file `name` in the folder; its path.
    #[allow(dead_code)] // not every test that includes this module writes text files
    pub fn write(&self, name: &str, text: &str) -> PathBuf {
        let p = self.0.join(name);
        std::fs::write(&p, text).unwrap();
        p
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        std::fs::remove_dir_all(&self.0).ok();
    }
}
