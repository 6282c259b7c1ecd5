//! A study in a network namespace of its own, with only loopback up: SITL binds its TCP ports on
//! every interface, so rows on the machine's own interfaces would collide with anything else
//! listening there. The command runs itself again under `unshare -n` (as root; else
//! `unshare -rn`, in a user namespace) and passes a signal that stopped it on to the copy.

use std::process::Command;
use std::sync::atomic::{AtomicBool, Ordering};

use crate::error::{Error, Result};

/// Set in the environment of a study that runs inside its own network namespace.
pub const INSIDE_NETNS: &str = "SAVSIM_STUDY_NETNS";

/// Run this same command again inside a network namespace of its own with only loopback up
/// (`unshare -n`, as root; else `unshare -rn`, a user namespace), and return its ending.
/// `None` when no namespace can be made here: the study runs in this process.
pub fn in_own_namespace(shutdown: &AtomicBool) -> Result<Option<Result<()>>> {
    let exe = std::env::current_exe().map_err(|e| Error::file("the savsim executable", e))?;
    for flags in ["-n", "-rn"] {
        let works = Command::new("unshare")
            .args([flags, "true"])
            .status()
            .is_ok_and(|s| s.success());
        if !works {
            continue;
        }
        let mut child = Command::new("unshare")
            .args([flags, "sh", "-c", "ip link set lo up && exec \"$0\" \"$@\""])
            .arg(&exe)
            .args(std::env::args_os().skip(1))
            .env(INSIDE_NETNS, "1")
            .spawn()
            .map_err(|e| Error::file("unshare", e))?;
        let status = wait_forwarding(&mut child, shutdown)?;
        let failed = format!("study: the run in its network namespace ended with {status}");
        return Ok(Some(match status.code() {
            Some(0) => Ok(()),
            // Its own usage error, already printed: the same exit code.
            Some(2) => Err(Error::Usage(failed)),
            _ => Err(Error::Runtime(failed)),
        }));
    }
    eprintln!(
        "study: no network namespace can be made here (`unshare -n`): SITL binds its TCP ports \
         on every interface"
    );
    Ok(None)
}

/// Wait for the study in its namespace (the same process as `unshare`: it execs), passing a
/// signal that stopped this one on to it as SIGTERM.
fn wait_forwarding(
    child: &mut std::process::Child,
    shutdown: &AtomicBool,
) -> Result<std::process::ExitStatus> {
    let mut forwarded = false;
    loop {
        if let Some(status) = child.try_wait().map_err(|e| Error::file("unshare", e))? {
            return Ok(status);
        }
        if shutdown.load(Ordering::Relaxed) && !forwarded {
            forwarded = true;
            let _ = Command::new("kill")
                .args(["-TERM", &child.id().to_string()])
                .status();
        }
        std::thread::sleep(std::time::Duration::from_millis(100));
    }
}
