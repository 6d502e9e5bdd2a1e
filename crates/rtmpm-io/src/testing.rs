//! Test support for the crates that write files: a temporary folder per test (cargo feature
//! `testing`, for dev-dependencies; always in this crate's own tests). The folder stays when
//! `RTMPM_KEEP_TEST_FILES` is set.

use std::fs;
use std::path::PathBuf;
use std::sync::atomic::{AtomicU64, Ordering};

/// A fresh, empty temporary folder for one test (removed on drop).
pub struct TestDir(pub PathBuf);

impl TestDir {
    /// A new folder named after `tag`, the process and a counter, emptied first.
    pub fn new(tag: &str) -> Self {
        static COUNTER: AtomicU64 = AtomicU64::new(0);
        let n = COUNTER.fetch_add(1, Ordering::Relaxed);
        let dir = std::env::temp_dir().join(format!(
            "rtmpm-io-test-{}-{}-{}",
            tag,
            std::process::id(),
            n
        ));
        let _ = fs::remove_dir_all(&dir);
        fs::create_dir_all(&dir).unwrap();
        TestDir(dir)
    }

    /// The path of `name` in the folder.
    pub fn path(&self, name: &str) -> PathBuf {
        self.0.join(name)
    }
}

impl Drop for TestDir {
    fn drop(&mut self) {
        if std::env::var_os("RTMPM_KEEP_TEST_FILES").is_none() {
            let _ = fs::remove_dir_all(&self.0);
        }
    }
}
