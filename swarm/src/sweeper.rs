//! Removing the bus nodes that dead robots leave behind, on a thread of its
//! own. With 1000 robots iceoryx2 takes about 3.7 s per dead node (it lists
//! all of `/dev/shm` once per port of the node; BENCHMARKS.md, build 0676a74),
//! and a launcher that swept in its own loop stopped reading the roster,
//! reporting and, in lockstep, ticking the clock for that long.

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc;
use std::thread::JoinHandle;
use std::time::SystemTime;

use shoal_broker::liveness::sweep_dead_nodes;
use shoal_runtime::SwarmRuntime;

pub struct Sweeper {
    /// When a death was noticed, one message per noticing; none once stopped.
    requests: Option<mpsc::Sender<SystemTime>>,
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<()>>,
}

impl Sweeper {
    /// A sweeper for the swarm `swarm`, whose folder is `runtime`.
    pub fn start(runtime: SwarmRuntime, swarm: String) -> std::io::Result<Self> {
        let (requests, noticed) = mpsc::channel::<SystemTime>();
        let stop = Arc::new(AtomicBool::new(false));
        let stopping = Arc::clone(&stop);
        let thread = std::thread::Builder::new()
            .name("sweeper".into())
            .spawn(move || {
                let go_on = || {
                    !stopping.load(Ordering::Relaxed) && !shoal_broker::bus::termination_signalled()
                };
                while let Ok(at) = noticed.recv() {
                    if !go_on() {
                        break;
                    }
                    // Deaths noticed before a sweep that has since finished
                    // started were swept by it, here or in a robot.
                    sweep_dead_nodes(&runtime, &swarm, at, true, go_on);
                }
            })?;
        Ok(Self {
            requests: Some(requests),
            stop,
            thread: Some(thread),
        })
    }

    /// Asks for the nodes of every robot dead by now to be removed.
    pub fn request(&self) {
        let Some(requests) = &self.requests else {
            return;
        };
        if requests.send(SystemTime::now()).is_err() {
            tracing::error!("the sweeper thread has ended; dead nodes are swept at the stop");
        }
    }

    /// Stops a sweep under way between two nodes. The thread is not waited
    /// for: it may be waiting for a robot's sweep to let go of the sweep
    /// lock, and a stopping swarm sweeps its nodes itself afterwards.
    pub fn stop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        self.requests = None;
        if let Some(thread) = self.thread.take_if(|t| t.is_finished())
            && thread.join().is_err()
        {
            tracing::error!("the sweeper thread panicked");
        }
    }
}

impl Drop for Sweeper {
    fn drop(&mut self) {
        self.stop();
    }
}
