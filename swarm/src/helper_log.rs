//! What a helper (recorder, SLAM) tells the user while it runs. Helpers
//! write to their logs in the swarm's folder, which nobody reads while the
//! run goes well; their warnings (a disk filling, a viewer gone) must reach
//! the launcher's terminal when they are said, not when the run ends.

use std::io::{Read, Seek, SeekFrom};
use std::path::PathBuf;

/// A line a helper means for the user: `<binary>: warning: ...`.
const WARNING: &str = ": warning: ";

/// Reads the lines a helper's log gained since the last look.
pub struct HelperLog {
    path: PathBuf,
    read_to: u64,
    /// A line not yet ended by a newline.
    partial: String,
}

impl HelperLog {
    pub fn new(path: PathBuf) -> Self {
        Self {
            path,
            read_to: 0,
            partial: String::new(),
        }
    }

    /// The warnings written since the last call. A log that cannot be read
    /// (removed with the swarm's folder) has none.
    pub fn new_warnings(&mut self) -> Vec<String> {
        let Ok(mut file) = std::fs::File::open(&self.path) else {
            return Vec::new();
        };
        let mut added = String::new();
        if file.seek(SeekFrom::Start(self.read_to)).is_err()
            || file.read_to_string(&mut added).is_err()
        {
            return Vec::new();
        }
        self.read_to += added.len() as u64;
        self.partial.push_str(&added);
        let Some(last_newline) = self.partial.rfind('\n') else {
            return Vec::new();
        };
        let rest = self.partial.split_off(last_newline + 1);
        let complete = std::mem::replace(&mut self.partial, rest);
        warnings_in(&complete)
    }
}

/// The user's warnings among complete log lines.
fn warnings_in(lines: &str) -> Vec<String> {
    lines
        .lines()
        .filter(|line| line.contains(WARNING))
        .map(str::to_owned)
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::io::Write;

    #[test]
    fn warnings_are_read_once_and_only_when_their_line_is_complete() {
        let dir = std::env::temp_dir().join(format!("shoal-helper-log-{}", std::process::id()));
        std::fs::create_dir_all(&dir).expect("folder");
        let path = dir.join("shoal-viewer-log.log");
        let mut file = std::fs::File::create(&path).expect("log");
        let mut log = HelperLog::new(path);
        assert!(log.new_warnings().is_empty());
        write!(file, "2026 INFO started\nshoal-viewer-log: warning: disk").expect("write");
        assert!(
            log.new_warnings().is_empty(),
            "the line is not complete yet"
        );
        writeln!(file, " nearly full").expect("write");
        assert_eq!(
            log.new_warnings(),
            vec!["shoal-viewer-log: warning: disk nearly full".to_owned()]
        );
        assert!(log.new_warnings().is_empty(), "each warning once");
        std::fs::remove_dir_all(dir).expect("cleanup");
    }
}
