//! The `shoal` command line's own pieces: `shoal up` (start a swarm and
//! watch it) and `shoal status`. Running a swarm is `shoal-swarm`; the
//! experiments and the demo are `shoal-lab`.

pub mod status;
pub mod up;
