//! One writer per output folder (issue 66): two runs into one `--out` fused their stats lines
//! and wrote a recording that did not decode. A command that writes takes an advisory lock on
//! `<out>/.skinsim.lock` and keeps it while it runs; the system releases it when the process
//! ends, however it ends, so a killed run leaves no stale lock. The holder writes who it is into
//! the file, for the refused command to name.

use std::fs::{File, OpenOptions, TryLockError};
use std::io::{Read, Seek, Write};
use std::path::Path;

/// The lock file's name inside the output folder.
pub const LOCK_FILE: &str = ".skinsim.lock";

/// The held lock; dropping it releases the folder.
#[derive(Debug)]
pub struct OutLock(#[allow(dead_code)] File);

/// Locks `out` (which must exist) for `command` ("run scenes/x.ron", "bake ..."), or says who
/// holds it.
pub fn lock(out: &Path, command: &str) -> Result<OutLock, String> {
    let path = out.join(LOCK_FILE);
    let open = OpenOptions::new().read(true).write(true).create(true).truncate(false).open(&path);
    let mut file = open.map_err(|e| format!("cannot open {}: {e}", path.display()))?;
    match file.try_lock() {
        Ok(()) => {
            let holder = format!("skinsim {command} (process {})\n", std::process::id());
            let written = file.set_len(0).and_then(|_| file.rewind()).and_then(|_| file.write_all(holder.as_bytes()));
            written.map_err(|e| format!("cannot write {}: {e}", path.display()))?;
            Ok(OutLock(file))
        }
        Err(TryLockError::WouldBlock) => {
            let mut holder = String::new();
            let _ = file.read_to_string(&mut holder);
            let holder = holder.trim();
            let holder = if holder.is_empty() { "another skinsim" } else { holder };
            Err(format!("{} is in use by {holder}; wait for it to end or choose another output folder", out.display()))
        }
        Err(TryLockError::Error(e)) => Err(format!("cannot lock {}: {e}", path.display())),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_second_writer_is_refused_by_name_until_the_first_ends() {
        let d = std::env::temp_dir().join(format!("skinsim-lock-{}", std::process::id()));
        std::fs::create_dir_all(&d).unwrap();
        let first = lock(&d, "run a.ron").unwrap();
        let refused = lock(&d, "run b.ron").unwrap_err();
        assert!(refused.contains("in use by skinsim run a.ron (process "), "{refused}");
        drop(first);
        let again = lock(&d, "run b.ron");
        assert!(again.is_ok(), "{again:?}");
    }
}
