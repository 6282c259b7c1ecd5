//! A thread that builds triangle meshes off the tick path: the sensing layer asks for the
//! meshes ahead of the vehicle, the worker builds them while the contact layer runs the
//! ticks in between, and the [`MeshCache`](crate::collision::meshes::MeshCache) installs them
//! at fixed points (the next sensing frame, or a contact that needs one), waiting only for a
//! build still running. What is resident at each decision therefore depends on the inputs
//! alone, never on how fast the worker was.
//!
//! One named thread (`savsim-meshes`) per cache that asks, started on the first request; it
//! ends when every handle to it is dropped. Jobs go over a bounded channel (a full one makes
//! the asker wait: the worker never waits on the asker, so neither can deadlock). A build that
//! panics, or a job the worker never reaches (its thread gone), fills its slot with a failure:
//! a waiter is always woken, and builds the mesh itself.

use std::panic::AssertUnwindSafe;
use std::sync::mpsc::{sync_channel, SyncSender};
use std::sync::{Arc, Condvar, Mutex};
use std::time::Duration;

use parry3d::shape::TriMesh;

use crate::scene::geometry::Geometry;

/// Jobs that may wait in the channel.
const QUEUE: usize = 256;

/// A finished build: the mesh and how long it took, or `None` when the worker failed.
type Built = Option<(Arc<TriMesh>, Duration)>;

/// Where one build's result appears.
#[derive(Debug, Default)]
pub(crate) struct Slot {
    result: Mutex<Option<Built>>,
    done: Condvar,
}

impl Slot {
    /// The mesh and how long it took to build, waiting for it if it is still being built;
    /// `None` when the worker failed on it (the caller builds it).
    pub fn wait(&self) -> Built {
        let mut result = self.result.lock().unwrap_or_else(|e| e.into_inner());
        loop {
            if let Some(done) = result.as_ref() {
                return done.clone();
            }
            result = self.done.wait(result).unwrap_or_else(|e| e.into_inner());
        }
    }

    fn fill(&self, built: Built) {
        let mut result = self.result.lock().unwrap_or_else(|e| e.into_inner());
        if result.is_none() {
            *result = Some(built);
        }
        self.done.notify_all();
    }
}

/// A job's hold on its slot: filled with a failure when dropped unfilled (a job dropped in the
/// channel, or by a worker that panicked), so that no waiter waits for ever.
struct Job {
    geometry: Geometry,
    slot: Arc<Slot>,
}

impl Drop for Job {
    fn drop(&mut self) {
        self.slot.fill(None);
    }
}

/// A handle to the worker (cheap to clone: clones share the thread).
#[derive(Debug, Clone)]
pub(crate) struct MeshWorker {
    jobs: SyncSender<Job>,
}

impl MeshWorker {
    /// Start the worker thread, or `None` if the system will not start one (the caller then
    /// builds on its own thread).
    pub fn start() -> Option<Self> {
        let (jobs, queue) = sync_channel::<Job>(QUEUE);
        std::thread::Builder::new()
            .name("savsim-meshes".into())
            .spawn(move || {
                for job in queue {
                    let started = std::time::Instant::now();
                    let built =
                        std::panic::catch_unwind(AssertUnwindSafe(|| job.geometry.build_trimesh()));
                    job.slot
                        .fill(built.ok().map(|mesh| (Arc::new(mesh), started.elapsed())));
                }
            })
            .ok()?;
        Some(Self { jobs })
    }

    /// Ask for `geometry`'s mesh; `None` if the worker is gone (build it yourself).
    pub fn request(&self, geometry: &Geometry) -> Option<Arc<Slot>> {
        let slot = Arc::new(Slot::default());
        let job = Job {
            geometry: geometry.clone(),
            slot: slot.clone(),
        };
        self.jobs.send(job).ok()?;
        Some(slot)
    }
}
