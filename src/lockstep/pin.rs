//! A lockstep row of one autopilot on one core.
//!
//! In lockstep savsim and the autopilot take turns: one computes while the other waits on a
//! socket. Left to the scheduler, the turn hands over from one core to the other at every
//! step, and waking an idle core is slow: a row on one core runs about twice as fast on a
//! quiet machine (docs/lockstep.md, "Speed", has the figures). Pinning the thread that starts
//! the row pins what it starts: a child process and a new thread inherit the mask of the
//! thread that made them (Linux).

use nix::sched::{sched_getaffinity, sched_setaffinity, CpuSet};
use nix::unistd::Pid;

/// The calling thread kept to one core until dropped, then given its cores back.
pub struct Pinned {
    before: Option<CpuSet>,
}

impl Pinned {
    /// Keep the calling thread (and what it starts from now on) to the `k`-th of the cores
    /// it may run on (counted round); nothing when the system refuses.
    pub fn to_core(k: usize) -> Pinned {
        let this = Pid::from_raw(0);
        let Ok(before) = sched_getaffinity(this) else {
            return Pinned { before: None };
        };
        let allowed: Vec<usize> = (0..CpuSet::count())
            .filter(|&c| before.is_set(c).unwrap_or(false))
            .collect();
        let mut one = CpuSet::new();
        let pinned = match allowed.get(k % allowed.len().max(1)) {
            Some(&cpu) => one.set(cpu).is_ok() && sched_setaffinity(this, &one).is_ok(),
            None => false,
        };
        Pinned {
            before: pinned.then_some(before),
        }
    }

    /// Whether the thread was pinned.
    pub fn is_pinned(&self) -> bool {
        self.before.is_some()
    }
}

impl Drop for Pinned {
    fn drop(&mut self) {
        if let Some(before) = &self.before {
            let _ = sched_setaffinity(Pid::from_raw(0), before);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cores_allowed() -> usize {
        let set = sched_getaffinity(Pid::from_raw(0)).unwrap();
        (0..CpuSet::count())
            .filter(|&c| set.is_set(c).unwrap())
            .count()
    }

    #[test]
    fn a_pinned_thread_runs_on_one_core_and_gets_its_cores_back() {
        let before = cores_allowed();
        {
            let pinned = Pinned::to_core(7);
            assert!(pinned.is_pinned());
            assert_eq!(cores_allowed(), 1);
            // What it starts inherits the mask.
            let inner = std::thread::Builder::new()
                .name("pinned-child".into())
                .spawn(cores_allowed)
                .unwrap();
            assert_eq!(inner.join().unwrap(), 1);
        }
        assert_eq!(cores_allowed(), before);
    }
}
