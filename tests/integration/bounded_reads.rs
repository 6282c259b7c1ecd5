//! Every file savsim reads whole is read within a bound: a device that never ends
//! (`/dev/zero`), a FIFO that keeps writing, or a file larger than its kind allows is a clear
//! error, never a read without end or an allocation without bound.

use std::io::Write;
use std::path::Path;
use std::time::{Duration, Instant};

use crate::cli::savsim;

/// `savsim ARGS` ends with an error naming the file (`/dev/zero`, or a link to it) as a device
/// within a few seconds.
fn refuses_dev_zero(args: &[&str]) {
    let started = Instant::now();
    let out = savsim().args(args).output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "{args:?}: {err}");
    assert!(
        err.contains("/dev/zero") || err.contains("zero.obj"),
        "{args:?}: {err}"
    );
    assert!(err.contains("device"), "{args:?}: {err}");
    assert!(started.elapsed() < Duration::from_secs(30), "{args:?}");
}

#[test]
#[cfg(unix)]
fn dev_zero_is_refused_wherever_a_file_is_read() {
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("s.toml");
    // A mesh file that is /dev/zero under a mesh's name.
    std::os::unix::fs::symlink("/dev/zero", dir.path().join("zero.obj")).unwrap();
    std::fs::write(
        &scene,
        "[origin]\nlat_deg = 0\nlon_deg = 0\nalt_m = 0\n\n[[obstacle]]\nid = \"m\"\nkind = \"building\"\nshape = { mesh = \"zero.obj\" }\nposition_enu_m = [0.0, 0.0, 0.0]\n",
    )
    .unwrap();
    let scene = scene.to_str().unwrap();
    refuses_dev_zero(&["scene", "info", "/dev/zero"]);
    refuses_dev_zero(&["scene", "info", scene]);
    refuses_dev_zero(&["replay", "/dev/zero"]);
    // The configuration and the scenario are read by one function (`daa_csv::read`).
    refuses_dev_zero(&["daa", "--conf", "/dev/zero", "x.daa"]);
    let out = dir.path().join("out");
    let out = out.to_str().unwrap();
    refuses_dev_zero(&["batch", "/dev/zero", "--out", out]);
    refuses_dev_zero(&["study", "/dev/zero", "--out", out]);
}

/// A FIFO whose writer never stops is read up to the bound, then refused.
#[test]
#[cfg(unix)]
fn a_fifo_that_keeps_writing_is_read_up_to_the_bound() {
    let dir = tempfile::tempdir().unwrap();
    let fifo = dir.path().join("fifo");
    let made = std::process::Command::new("mkfifo")
        .arg(&fifo)
        .status()
        .unwrap();
    assert!(made.success());
    let writer = std::thread::spawn({
        let fifo = fifo.clone();
        move || {
            let mut f = std::fs::OpenOptions::new().write(true).open(fifo).unwrap();
            // Until the reader closes its end (a broken pipe).
            while f.write_all(&[b'x'; 4096]).is_ok() {}
        }
    });
    let err = savsim::files::read(&fifo, 1 << 20).unwrap_err();
    assert_eq!(err.kind(), std::io::ErrorKind::InvalidData);
    assert!(
        err.to_string().contains("larger than 1048576 bytes"),
        "{err}"
    );
    writer.join().unwrap();
    // A file within its bound is read whole.
    let small = dir.path().join("small");
    std::fs::write(&small, b"abc").unwrap();
    assert_eq!(savsim::files::read(Path::new(&small), 3).unwrap(), b"abc");
}

/// ULog files under 1 KiB whose formats would take gigabytes, or never end, flattened
/// (scripts/crafted_ulog.py): a clear error naming the topic, exit code 2.
#[test]
fn crafted_ulogs_are_refused_by_their_format() {
    let dir = tempfile::tempdir().unwrap();
    crate::common::python(
        &crate::common::root().join("scripts/crafted_ulog.py"),
        &[dir.path().to_str().unwrap()],
    );
    for name in ["huge_array.ulg", "endless_count.ulg", "nested.ulg"] {
        let path = dir.path().join(name);
        assert!(std::fs::metadata(&path).unwrap().len() < 1024);
        let out = savsim().arg("replay").arg(&path).output().unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{name}: {err}");
        assert!(err.contains("ULog format of topic"), "{name}: {err}");
    }
}
