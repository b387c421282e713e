//! Free space for the recording, seen before it runs out.

use std::collections::VecDeque;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

/// What a recording takes per robot per second of run (at 5 Hz, SLAM's
/// particles and maps aside), as measured (BENCHMARKS.md, "Recording"):
/// 1504 B with 20 robots, where each frame's own chunks weigh more, 817 B
/// with 100 and 830 B with 1000. Between them it is interpolated.
const MEASURED_BYTES_PER_ROBOT_SECOND: [(f64, f64); 3] =
    [(20.0, 1504.0), (100.0, 817.0), (1000.0, 830.0)];
/// Warn once when the space left holds less recording than this.
const WARN_WHEN_LEFT: Duration = Duration::from_secs(60);
/// The write rate is measured over this much of the recent run.
const RATE_WINDOW: Duration = Duration::from_secs(10);

/// Bytes the unprivileged user may still write on the file system of `dir`.
pub fn free_bytes(dir: &Path) -> Option<u64> {
    let stat = rustix::fs::statvfs(dir).ok()?;
    Some(stat.f_bavail.saturating_mul(stat.f_frsize))
}

/// The folder a file goes into (`.` for a bare file name).
pub fn folder_of(file: &Path) -> PathBuf {
    match file.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_owned(),
        _ => PathBuf::from("."),
    }
}

/// The bytes a recording of `robots` takes per second of run.
pub fn bytes_per_second(robots: usize) -> f64 {
    let n = robots as f64;
    let table = MEASURED_BYTES_PER_ROBOT_SECOND;
    let per_robot = match table.iter().position(|(at, _)| n <= *at) {
        Some(0) => table[0].1,
        None => table[table.len() - 1].1,
        Some(i) => {
            let ((n0, b0), (n1, b1)) = (table[i - 1], table[i]);
            b0 + (b1 - b0) * (n - n0) / (n1 - n0)
        }
    };
    per_robot * n
}

/// The warning for a run of `robots` for `seconds` when it will not fit in
/// `free` bytes beside the `written` already (the arena, the first frames).
pub fn estimate_warning(free: u64, written: u64, robots: usize, seconds: f64) -> Option<String> {
    let rate = bytes_per_second(robots);
    let needed = (rate * seconds.max(0.0)) as u64;
    (needed > free).then(|| {
        format!(
            "the recording of {robots} robots for {seconds:.0} s takes about {} more \
             (beside the {} written), and its file system has {} free: it holds about \
             the first {:.0} s",
            human_bytes(needed),
            human_bytes(written),
            human_bytes(free),
            free as f64 / rate
        )
    })
}

pub fn human_bytes(bytes: u64) -> String {
    const UNITS: [&str; 5] = ["B", "KB", "MB", "GB", "TB"];
    let mut value = bytes as f64;
    let mut unit = 0;
    while value >= 1000.0 && unit + 1 < UNITS.len() {
        value /= 1000.0;
        unit += 1;
    }
    if unit == 0 {
        format!("{bytes} B")
    } else {
        format!("{value:.1} {}", UNITS[unit])
    }
}

/// Watches the recording's write rate against the space left, and says
/// once when less than a minute of recording fits.
pub struct SpaceWatch {
    folder: PathBuf,
    written: VecDeque<(Instant, u64)>,
    warned: bool,
}

impl SpaceWatch {
    pub fn new(file: &Path) -> Self {
        Self {
            folder: folder_of(file),
            written: VecDeque::new(),
            warned: false,
        }
    }

    /// Notes that `bytes` have been written by `now`; the warning, the
    /// first time less than a minute of recording is left.
    pub fn check(&mut self, now: Instant, bytes: u64) -> Option<String> {
        self.written.push_back((now, bytes));
        while self
            .written
            .front()
            .is_some_and(|(t, _)| now.duration_since(*t) > RATE_WINDOW)
        {
            self.written.pop_front();
        }
        if self.warned {
            return None;
        }
        let (since, then) = *self.written.front()?;
        let elapsed = now.duration_since(since).as_secs_f64();
        if elapsed < 1.0 || bytes <= then {
            return None;
        }
        let rate = (bytes - then) as f64 / elapsed;
        let free = free_bytes(&self.folder)?;
        let left = Duration::from_secs_f64(free as f64 / rate);
        (left < WARN_WHEN_LEFT).then(|| {
            self.warned = true;
            format!(
                "less than a minute of recording left: {} free on the file system of {} \
                 at {}/s (about {} s)",
                human_bytes(free),
                self.folder.display(),
                human_bytes(rate as u64),
                left.as_secs()
            )
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_run_that_does_not_fit_is_warned_of_with_what_fits() {
        // 20 robots write 30.1 KB/s: 60 s take 1.8 MB; 600 KB hold about 20 s.
        let said = estimate_warning(600_000, 150_000, 20, 60.0).expect("a warning");
        assert!(said.contains("1.8 MB"), "{said}");
        assert!(said.contains("first 20 s"), "{said}");
        assert_eq!(estimate_warning(10_000_000, 150_000, 20, 60.0), None);
    }

    #[test]
    fn the_rate_follows_the_measured_table_between_its_rows() {
        assert_eq!(bytes_per_second(20), 20.0 * 1504.0);
        assert_eq!(bytes_per_second(1000), 1000.0 * 830.0);
        assert_eq!(bytes_per_second(5000), 5000.0 * 830.0);
        let at_60 = bytes_per_second(60) / 60.0;
        assert!((at_60 - (1504.0 + 817.0) / 2.0).abs() < 1e-9, "{at_60}");
    }

    #[test]
    fn the_folder_of_a_bare_file_name_is_the_current_one() {
        assert_eq!(folder_of(Path::new("run.rrd")), PathBuf::from("."));
        assert_eq!(folder_of(Path::new("/a/b.rrd")), PathBuf::from("/a"));
        assert!(free_bytes(Path::new(".")).is_some());
    }
}
