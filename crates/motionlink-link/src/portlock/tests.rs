//! The lock files themselves: names, taking, stale files, removal, the outcome a stopped holder leaves.
#![cfg_attr(not(unix), allow(dead_code, unused_imports))]

use super::*;

/// A directory of its own for each test (removed at the end of the test).
struct TempDir(PathBuf);

impl TempDir {
    fn new(name: &str) -> TempDir {
        let dir = std::env::temp_dir().join(format!("motionlink-lock-test-{}-{name}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        TempDir(dir)
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

fn holder(pid: u32) -> Holder {
    Holder { pid, port: "tcp://127.0.0.1:4000".into(), family: "scu".into(), command: "scu move 1 400".into() }
}

/// A pid no process has: above every Unix's pid limit (Linux allows at most 2^22).
const DEAD_PID: u32 = 2_000_000_000;

#[test]
fn names_keep_what_reads_and_differ_where_the_ports_differ() {
    let usb = file_stem("/dev/ttyUSB0");
    assert!(usb.starts_with("dev_ttyUSB0-") && usb.len() == "dev_ttyUSB0-".len() + 16, "{usb}");
    let tcp = file_stem("tcp://127.0.0.1:4000");
    assert!(tcp.starts_with("tcp_127.0.0.1_4000-"), "{tcp}");
    for name in [&usb, &tcp] {
        assert!(name.chars().all(|c| c.is_ascii_alphanumeric() || "._-".contains(c)), "{name}");
    }
    // The same once sanitised, not the same port: the hash tells them apart.
    let (a, b) = (file_stem("/dev/tty/USB0"), file_stem("/dev/tty_USB0"));
    assert_eq!(a[..a.len() - 16], b[..b.len() - 16]);
    assert_ne!(a, b);
    // A long path is cut, never a path separator or a dot-dot in the name.
    let long = file_stem(&format!("/dev/{}", "x".repeat(300)));
    assert!(long.len() <= 64 + 17, "{long}");
    assert!(!file_stem("../../etc/passwd").contains('/'));
}

#[test]
fn only_exclusive_ports_have_a_lock_and_one_port_has_one_key() {
    let key = |p: &str| lock_key(&p.parse::<PortUrl>().unwrap());
    assert_eq!(key("sim"), None);
    assert_eq!(key("socketcan://can0"), None);
    assert_eq!(key("tcp://LocalHost:4000"), Some("tcp://localhost:4000".into()));
    assert_eq!(key("slcan://tcp://localhost:4000"), key("tcp://localhost:4000"));
    // A device path is taken as the file it is (a link to a device is the device).
    let dir = TempDir::new("key");
    std::fs::create_dir_all(&dir.0).unwrap();
    let real = dir.0.join("ttyUSB0");
    std::fs::write(&real, "").unwrap();
    let real = std::fs::canonicalize(&real).unwrap();
    #[cfg(unix)]
    {
        let link = dir.0.join("by-id");
        std::os::unix::fs::symlink(&real, &link).unwrap();
        assert_eq!(key(&link.display().to_string()), Some(real.display().to_string()));
    }
    assert_eq!(key(&real.display().to_string()), key(&format!("slcan://{}", real.display())));
}

#[cfg(unix)]
#[test]
fn a_held_lock_names_its_holder_and_is_removed_when_dropped() {
    let dir = TempDir::new("held");
    let locks = LockDir::new(&dir.0);
    let key = "tcp://127.0.0.1:4000";
    let me = holder(std::process::id());
    let Acquired::Locked { lock, stale: None } = locks.acquire(key, &me).unwrap() else { panic!("not locked") };
    let path = locks.lock_path(key);
    let named: Holder = serde_json::from_str(&std::fs::read_to_string(&path).unwrap()).unwrap();
    assert_eq!(named, me);
    // Another open file of the same lock (as another process would have) finds it held, and by whom.
    match locks.acquire(key, &holder(1)).unwrap() {
        Acquired::Held(Some(h)) => assert_eq!(h, me),
        other => panic!("{other:?}"),
    }
    drop(lock);
    assert!(!path.exists(), "removed when released");
    assert!(matches!(locks.acquire(key, &holder(7)).unwrap(), Acquired::Locked { stale: None, .. }));
    // The directory is this user's alone.
    use std::os::unix::fs::PermissionsExt;
    assert_eq!(std::fs::metadata(&dir.0).unwrap().permissions().mode() & 0o777, 0o700);
}

#[cfg(unix)]
#[test]
fn a_file_left_by_a_dead_process_is_stale_and_replaced() {
    let dir = TempDir::new("stale");
    let locks = LockDir::new(&dir.0);
    let key = "/dev/ttyUSB0";
    os::private_dir(&dir.0).unwrap();
    std::fs::write(locks.lock_path(key), serde_json::to_string(&holder(DEAD_PID)).unwrap()).unwrap();
    assert!(!os::alive(DEAD_PID));
    let me = holder(std::process::id());
    let Acquired::Locked { lock, stale } = locks.acquire(key, &me).unwrap() else { panic!("the stale file won") };
    assert_eq!(stale.map(|h| h.pid), Some(DEAD_PID));
    let named: Holder = serde_json::from_str(&std::fs::read_to_string(locks.lock_path(key)).unwrap()).unwrap();
    assert_eq!(named.pid, std::process::id());
    drop(lock);
    // A file with no name in it (a holder that died before writing) is stale too.
    std::fs::write(locks.lock_path(key), "").unwrap();
    assert!(matches!(locks.acquire(key, &me).unwrap(), Acquired::Locked { stale: None, .. }));
}

#[cfg(unix)]
#[test]
fn a_holder_asked_to_stop_leaves_its_outcome_and_one_not_asked_leaves_none() {
    let dir = TempDir::new("outcome");
    let locks = LockDir::new(&dir.0);
    let key = "tcp://127.0.0.1:4000";
    let me = std::process::id();
    let Acquired::Locked { lock, .. } = locks.acquire(key, &holder(me)).unwrap() else { panic!() };
    assert_eq!(lock.stop_request(), None);
    // A request for another holder (one that has gone) is not this one's.
    let stale = StopRequest { holder_pid: DEAD_PID, pid: 42, command: "scu stop".into() };
    locks.request_stop(key, &stale).unwrap();
    assert_eq!(lock.stop_request(), None);
    let request = StopRequest { holder_pid: me, pid: 42, command: "scu stop".into() };
    locks.request_stop(key, &request).unwrap();
    assert_eq!(lock.stop_request(), Some(request));
    lock.release("scu move 1 400", 130, "cancelled; A1 stopped at 24 counts");
    assert!(!locks.lock_path(key).exists());
    let outcome = locks.take_outcome(key, me).expect("the outcome");
    assert_eq!((outcome.exit_code, outcome.requested_by), (130, 42));
    assert_eq!(outcome.message, "cancelled; A1 stopped at 24 counts");
    assert_eq!(locks.take_outcome(key, me), None, "taken once, and the request with it");
    assert_eq!(std::fs::read_dir(&dir.0).unwrap().count(), 0, "nothing left behind");
    // Not asked: no outcome.
    let Acquired::Locked { lock, .. } = locks.acquire(key, &holder(me)).unwrap() else { panic!() };
    lock.release("scu get", 0, "");
    assert_eq!(locks.take_outcome(key, me), None);
}

#[cfg(unix)]
#[test]
fn a_directory_others_may_write_to_is_refused() {
    use std::os::unix::fs::PermissionsExt;
    let dir = TempDir::new("open");
    std::fs::create_dir_all(&dir.0).unwrap();
    std::fs::set_permissions(&dir.0, std::fs::Permissions::from_mode(0o777)).unwrap();
    let e = LockDir::new(&dir.0).acquire("tcp://h:1", &holder(1)).unwrap_err();
    assert!(e.to_string().contains("others may write"), "{e}");
}
