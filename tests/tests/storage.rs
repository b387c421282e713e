//! Storage faults a lab meets every week: a disk that fills, a disk that
//! fails, a recorder frozen at shutdown, a swarm killed whole. Each run is
//! real (robot processes on iceoryx2, a recorder writing a real `.rrd`),
//! and each recording is read back with the official Rerun reader.
//!
//! Mounting file systems needs root (CI runs as root); without it the
//! tests that need a mount say so and pass without running.

use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Duration;

use shoal_e2e::{
    BackgroundSwarm, alive_ids, bin, inspect_recording, residue, scratch, serial, shoal, status,
    wait_until,
};

/// A file system mounted for one test, unmounted when dropped (an image
/// file behind it stays, for the test's folder to remove).
struct Mount {
    dir: PathBuf,
}

impl Mount {
    /// A tmpfs of `size` (e.g. "600k") at `dir`; None when this user
    /// cannot mount.
    fn tmpfs(dir: &Path, size: &str) -> Option<Self> {
        std::fs::create_dir_all(dir).expect("mount point");
        let mounted = Command::new("mount")
            .args(["-t", "tmpfs", "-o", &format!("size={size}"), "tmpfs"])
            .arg(dir)
            .status()
            .is_ok_and(|s| s.success());
        mounted.then(|| Self {
            dir: dir.to_owned(),
        })
    }

    /// A small ext4 file system in an image file, on a loop device.
    fn ext4(dir: &Path, image: &Path) -> Option<Self> {
        std::fs::create_dir_all(dir).expect("mount point");
        let made = Command::new("truncate")
            .args(["-s", "64M"])
            .arg(image)
            .status()
            .is_ok_and(|s| s.success())
            && Command::new("mkfs.ext4")
                .args(["-q", "-F"])
                .arg(image)
                .status()
                .is_ok_and(|s| s.success());
        let mounted = made
            && Command::new("mount")
                .args(["-o", "loop"])
                .arg(image)
                .arg(dir)
                .status()
                .is_ok_and(|s| s.success());
        mounted.then(|| Self {
            dir: dir.to_owned(),
        })
    }

    /// Makes every later write on this ext4 fail with EIO, as a disk that
    /// dies does (ext4's shutdown ioctl, which `xfs_io -c shutdown` uses).
    /// Linux refuses to remount a file system read-only while a file on it
    /// is open for writing, so this is how a test fails a disk mid-write.
    fn fail_disk(&self) {
        let script = "import fcntl, os, sys\n\
                      fd = os.open(sys.argv[1], os.O_RDONLY)\n\
                      fcntl.ioctl(fd, 0x8004587D, (0).to_bytes(4, 'little'))\n";
        let done = Command::new("python3")
            .args(["-c", script])
            .arg(&self.dir)
            .status()
            .expect("python3");
        assert!(done.success(), "the shutdown ioctl failed");
    }
}

impl Drop for Mount {
    fn drop(&mut self) {
        // Processes that wrote here may take a moment to let go of it.
        let unmounted = wait_until(Duration::from_secs(10), || {
            Command::new("umount")
                .arg(&self.dir)
                .stderr(std::process::Stdio::null())
                .status()
                .is_ok_and(|s| s.success())
        });
        if !unmounted {
            let _ = Command::new("umount").arg("-l").arg(&self.dir).status();
        }
    }
}

fn cannot_mount(test: &str) {
    eprintln!("{test}: not run: mounting a file system needs root");
}

/// `agents` robots of swarm `name` recording into `recording` (with
/// `extra` arguments of `shoal up`), every robot alive.
fn recording_swarm(name: &str, agents: usize, recording: &Path, extra: &[&str]) -> BackgroundSwarm {
    let agents_text = agents.to_string();
    let mut args = vec![
        "--agents",
        agents_text.as_str(),
        "--record",
        recording.to_str().expect("utf-8"),
    ];
    args.extend_from_slice(extra);
    let mut swarm = BackgroundSwarm::start(name, &args);
    swarm.wait_alive(agents, Duration::from_secs(30));
    swarm
}

/// The recorder's process, found by its node on the swarm's bus.
fn recorder_pid(swarm: &str) -> Option<i32> {
    shoal_broker::liveness::swarm_nodes(swarm)
        .ok()?
        .into_iter()
        .find(|n| n.name.contains("/recorder-"))
        .map(|n| n.pid)
}

#[test]
fn a_recording_onto_a_disk_that_fills_is_reported_at_once_kept_readable_and_fails_the_run() {
    let _turn = serial();
    let dir = scratch("full-disk");
    let Some(mount) = Mount::tmpfs(&dir.join("small"), "600k") else {
        return cannot_mount("full disk");
    };
    let recording = mount.dir.join("run.rrd");
    let mut swarm = recording_swarm("e2e-full-disk", 20, &recording, &["--duration", "25"]);
    // Said while the swarm runs, not at its end.
    let said_at_once = wait_until(Duration::from_secs(20), || {
        swarm.log().contains("No space left on device")
    });
    let robots_then = alive_ids(&status(&swarm.name)).len();
    let (exit, said) = swarm.wait_end();
    eprintln!("full disk: shoal up {exit}:\n{said}");
    assert!(
        said_at_once,
        "no word of the full disk during the run:\n{said}"
    );
    assert_eq!(
        robots_then, 20,
        "the robots stopped with the recorder:\n{said}"
    );
    assert!(
        !exit.success(),
        "a lost recording must fail the run:\n{said}"
    );
    for words in [
        "cannot write the recording",
        recording.to_str().expect("utf-8"),
        "the file holds the run up to tick",
        "free space on that file system",
    ] {
        assert!(said.contains(words), "`{words}` not said:\n{said}");
    }
    // The run went on to its end with every robot.
    assert!(said.contains("shoal: 20 robots"), "{said}");
    let found = inspect_recording(&recording);
    eprintln!("full disk: the reader read {} ticks", found["ticks"]);
    assert!(
        found["ticks"].as_u64().is_some_and(|t| t > 0),
        "nothing readable kept: {found}"
    );
    drop(mount);
    let _ = std::fs::remove_dir_all(dir);
}

#[test]
fn a_disk_that_fails_mid_run_is_reported_and_what_was_written_stays_readable() {
    let _turn = serial();
    let dir = scratch("failing-disk");
    let Some(mount) = Mount::ext4(&dir.join("disk"), &dir.join("disk.img")) else {
        return cannot_mount("failing disk");
    };
    let recording = mount.dir.join("run.rrd");
    let tum = mount.dir.join("tum");
    let tum = tum.to_str().expect("utf-8");
    let mut swarm = recording_swarm(
        "e2e-failing-disk",
        6,
        &recording,
        &["--duration", "14", "--tum", tum],
    );
    std::thread::sleep(Duration::from_secs(4));
    mount.fail_disk();
    let (exit, said) = swarm.wait_end();
    eprintln!("failing disk: shoal up {exit}:\n{said}");
    assert!(!exit.success(), "a failed disk must fail the run:\n{said}");
    assert!(
        said.contains("Input/output error") && said.contains("tick"),
        "the fault, with where the recording ends, not said:\n{said}"
    );
    assert!(said.contains("shoal: 6 robots"), "{said}");
    // What reached the disk before it failed is read back in full. The
    // image is read through a fresh mount, as after a reboot.
    let image = dir.join("disk.img");
    let kept = dir.join("kept.rrd");
    drop(mount);
    let again = Mount::ext4_existing(&dir.join("disk"), &image);
    std::fs::copy(dir.join("disk").join("run.rrd"), &kept).expect("copy the recording");
    drop(again);
    let found = inspect_recording(&kept);
    eprintln!("failing disk: the reader read {} ticks", found["ticks"]);
    assert!(
        found["ticks"].as_u64().is_some_and(|t| t > 0),
        "nothing readable kept: {found}"
    );
    let _ = std::fs::remove_dir_all(dir);
}

impl Mount {
    /// Mounts an ext4 image made earlier.
    fn ext4_existing(dir: &Path, image: &Path) -> Self {
        let mut said = String::new();
        let mounted = wait_until(Duration::from_secs(10), || {
            let out = Command::new("mount")
                .args(["-o", "loop"])
                .arg(image)
                .arg(dir)
                .output()
                .expect("mount");
            said = String::from_utf8_lossy(&out.stderr).into_owned();
            out.status.success()
        });
        assert!(mounted, "mounting {} again: {said}", image.display());
        Self {
            dir: dir.to_owned(),
        }
    }
}

#[test]
fn a_recorder_over_its_file_size_limit_stops_with_a_clear_error_and_a_readable_file() {
    // Needs no root: a file-size limit (ulimit -f, SIGXFSZ ignored) makes
    // a write fail with EFBIG, as a file system's size limit does.
    let _turn = serial();
    let dir = scratch("file-size-limit");
    let recording = dir.join("run.rrd");
    let mut swarm = BackgroundSwarm::start("e2e-fsize", &["--agents", "6"]);
    swarm.wait_alive(6, Duration::from_secs(30));
    let recorder = Command::new("bash")
        .args([
            "-c",
            "trap '' XFSZ; ulimit -f 400; exec \"$0\" \"$1\" --swarm \"$2\" --duration 30",
        ])
        .arg(bin("shoal-viewer-log"))
        .arg(&recording)
        .arg(&swarm.name)
        .output()
        .expect("run the recorder");
    let said = String::from_utf8_lossy(&recorder.stderr);
    eprintln!(
        "file-size limit: shoal-viewer-log {}:\n{said}",
        recorder.status
    );
    assert!(!recorder.status.success(), "{said}");
    assert!(
        said.contains("File too large") && said.contains("cannot write the recording"),
        "{said}"
    );
    assert_eq!(alive_ids(&status(&swarm.name)).len(), 6, "robots ran on");
    let found = inspect_recording(&recording);
    eprintln!("file-size limit: the reader read {} ticks", found["ticks"]);
    assert!(found["ticks"].as_u64().is_some_and(|t| t > 0), "{found}");
    let _ = std::fs::remove_dir_all(dir);
}

#[test]
fn a_recorder_frozen_at_shutdown_is_killed_named_and_its_file_stays_readable() {
    let _turn = serial();
    let dir = scratch("frozen-recorder");
    let recording = dir.join("run.rrd");
    let mut swarm = recording_swarm("e2e-frozen-recorder", 4, &recording, &[]);
    std::thread::sleep(Duration::from_secs(3));
    let pid = recorder_pid(&swarm.name).expect("the recorder is on the bus");
    // SAFETY: plain kill(2) on the recorder this test's swarm started.
    unsafe { libc::kill(pid, libc::SIGSTOP) };
    let started = std::time::Instant::now();
    let (exit, said) = swarm.interrupt();
    let took = started.elapsed();
    eprintln!("frozen recorder: shoal up {exit} after {took:?}:\n{said}");
    assert!(
        said.contains("shoal-viewer-log did not stop within 10 s of SIGTERM and was killed"),
        "{said}"
    );
    assert!(said.contains("ends at its last flush"), "{said}");
    assert!(took < Duration::from_secs(30), "stopping took {took:?}");
    assert!(exit.success(), "{said}");
    let found = inspect_recording(&recording);
    eprintln!("frozen recorder: the reader read {} ticks", found["ticks"]);
    assert!(found["ticks"].as_u64().is_some_and(|t| t >= 5), "{found}");
    let _ = std::fs::remove_dir_all(dir);
}

#[test]
fn a_lockstep_swarm_killed_whole_leaves_nothing_once_another_swarm_starts() {
    let _turn = serial();
    let first = "e2e-killed-whole";
    let mut swarm = BackgroundSwarm::start(first, &["--agents", "3", "--lockstep"]);
    swarm.wait_alive(3, Duration::from_secs(30));
    // SAFETY: plain kill(2) on our own child.
    unsafe { libc::kill(swarm.pid(), libc::SIGKILL) };
    let _ = swarm.wait_end();
    assert!(
        wait_until(Duration::from_secs(10), || {
            shoal_broker::liveness::swarm_nodes(first)
                .is_ok_and(|nodes| nodes.iter().all(|n| !shoal_e2e::pid_alive(n.pid)))
        }),
        "the robots outlived their lockstep launcher"
    );
    assert_ne!(
        residue(first),
        (0, vec![]),
        "the kill left nothing to sweep"
    );
    let mut other = BackgroundSwarm::start("e2e-after-kill", &["--agents", "2", "--duration", "3"]);
    let (exit, said) = other.wait_end();
    eprintln!("killed whole, then another swarm: shoal up {exit}:\n{said}");
    assert!(exit.success(), "{said}");
    assert!(
        said.contains(&format!("of swarm `{first}`")),
        "the sweep was not said:\n{said}"
    );
    assert_eq!(
        residue(first),
        (0, vec![]),
        "nodes or services of `{first}` left"
    );
    let _ = shoal(&["down", "--swarm", first]);
}

#[test]
fn counts_and_ranges_that_cannot_make_a_run_are_refused_before_anything_starts() {
    for (args, words) in [
        (vec!["up", "--agents", "0"], "at least one robot"),
        (vec!["up", "--duration", "0"], "positive number of seconds"),
        (vec!["up", "--duration", "-5"], "positive number of seconds"),
        (vec!["up", "--agents", "100000"], "at most 65536 robots"),
        (
            vec!["up", "--agents", "10", "--first-id", "65530"],
            "would pass the highest id",
        ),
        (vec!["spawn", "--count", "0"], "at least one robot"),
        (vec!["demo", "--seconds", "0"], "positive number of seconds"),
    ] {
        let out = shoal(&args);
        let said = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success(), "{args:?} ran:\n{said}");
        assert!(
            said.contains(words),
            "{args:?}: `{words}` not said:\n{said}"
        );
        for premature in ["swarm `", "iceoryx2 keeps", "open "] {
            assert!(
                !said.contains(premature),
                "{args:?} said `{premature}` before refusing:\n{said}"
            );
        }
    }
}
