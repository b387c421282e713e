//! A termination signal is never lost, even when it arrives while the
//! process creates shared memory (iceoryx2 clears its last-signal slot
//! then). Its own test binary: the signal ends every bus loop of the
//! process that receives it.

use shoal_broker::{Bus, BusLimits};

#[test]
fn a_sigterm_before_services_are_opened_is_still_seen_after() {
    let swarm = format!("signals-{}", std::process::id());
    let bus = Bus::join_tool(&swarm, "test", BusLimits::default()).expect("join the bus");
    assert!(!bus.termination_requested());
    // SAFETY: raising a signal this process handles (iceoryx2's and
    // signal-hook's handlers are installed by `join`).
    assert_eq!(unsafe { libc::raise(libc::SIGTERM) }, 0);
    // Opening services creates and zeroes shared memory, which clears
    // iceoryx2's record of the signal.
    let roster = shoal_broker::roster::publisher(&bus).expect("roster");
    let reader = shoal_broker::roster::reader(&bus).expect("reader");
    let streams = shoal_broker::robot_streams::scan_publisher(&bus, 3).expect("scans");
    assert!(bus.termination_requested(), "the SIGTERM was lost");
    // And it stays requested: every loop of the process ends by it.
    assert!(bus.termination_requested());
    drop((roster, reader, streams));
}
