//! What the port lock needs of the operating system: an advisory lock on an open file (`flock`), whether a
//! process is alive and is motionlink, SIGINT, and a private directory. Unix only; elsewhere every port is
//! opened without a lock file ([`SUPPORTED`] is false) and a port in use gives the driver's plain message.

use std::fs::File;
use std::path::Path;

/// True where lock files are made (Unix).
pub const SUPPORTED: bool = cfg!(unix);

/// What trying to lock a file found.
#[derive(Debug, PartialEq, Eq)]
pub enum Try {
    /// This process holds the lock now.
    Locked,
    /// Another open file holds it.
    Held,
}

#[cfg(unix)]
mod imp {
    use std::fs::{DirBuilder, File, OpenOptions};
    use std::io;
    use std::os::unix::fs::{DirBuilderExt, MetadataExt, OpenOptionsExt};
    use std::os::unix::io::AsRawFd;
    use std::path::Path;

    use super::Try;

    /// Opens (creating it, mode 0600) the lock file at `path` for reading and writing.
    pub fn open(path: &Path) -> io::Result<File> {
        OpenOptions::new().read(true).write(true).create(true).truncate(false).mode(0o600).open(path)
    }

    /// An exclusive `flock` on `file`, without waiting. The lock belongs to the open file: it goes when the
    /// file is closed, also when the process dies in any way.
    pub fn try_lock(file: &File) -> io::Result<Try> {
        loop {
            // SAFETY: flock on a descriptor this File owns.
            let rc = unsafe { libc::flock(file.as_raw_fd(), libc::LOCK_EX | libc::LOCK_NB) };
            if rc == 0 {
                return Ok(Try::Locked);
            }
            let e = io::Error::last_os_error();
            match e.raw_os_error() {
                Some(libc::EINTR) => continue,
                Some(libc::EWOULDBLOCK) => return Ok(Try::Held),
                _ => return Err(e),
            }
        }
    }

    /// True when `path` still names the file `file` is (it was not removed or replaced meanwhile).
    pub fn same_file(file: &File, path: &Path) -> bool {
        match (file.metadata(), std::fs::metadata(path)) {
            (Ok(a), Ok(b)) => a.dev() == b.dev() && a.ino() == b.ino(),
            _ => false,
        }
    }

    /// True while process `pid` exists (a zombie counts: it exists until its parent reaps it).
    pub fn alive(pid: u32) -> bool {
        let Ok(pid) = i32::try_from(pid) else { return false };
        if pid <= 0 {
            return false;
        }
        // SAFETY: signal 0 sends nothing; it only checks that the process exists.
        let rc = unsafe { libc::kill(pid, 0) };
        rc == 0 || io::Error::last_os_error().raw_os_error() == Some(libc::EPERM)
    }

    /// Whether process `pid` runs motionlink: on Linux its command name (`/proc/PID/comm`) is this
    /// program's, `motionlink` or `motionlink-...` (`motionlink-gateway`); `None` where that cannot be read (another Unix: the lock file's `flock`,
    /// which only the process that wrote the pid holds, is then the proof).
    pub fn is_motionlink(pid: u32) -> Option<bool> {
        let comm = |p: &str| std::fs::read_to_string(format!("/proc/{p}/comm")).ok().map(|s| s.trim().to_string());
        let theirs = comm(&pid.to_string())?;
        let ours = comm("self");
        // `motionlink`, or `motionlink-gateway` (the fleet gateway alone; a name is cut to 15 bytes there).
        Some(theirs == "motionlink" || theirs.starts_with("motionlink-") || Some(&theirs) == ours.as_ref())
    }

    /// Sends SIGINT to `pid`, as Ctrl-C in its terminal would.
    pub fn interrupt(pid: u32) -> io::Result<()> {
        let pid = i32::try_from(pid).map_err(|_| io::Error::other(format!("{pid} is no process id")))?;
        // SAFETY: kill(2) with a checked positive pid and SIGINT.
        if unsafe { libc::kill(pid, libc::SIGINT) } == 0 {
            Ok(())
        } else {
            Err(io::Error::last_os_error())
        }
    }

    /// The user's id.
    pub fn uid() -> u32 {
        // SAFETY: getuid has no preconditions.
        unsafe { libc::getuid() }
    }

    /// Makes `dir` (mode 0700) if missing, and checks it is this user's and nobody else may write to it: a
    /// directory someone else controls could hold lock files that send this program's SIGINT elsewhere.
    pub fn private_dir(dir: &Path) -> io::Result<()> {
        match DirBuilder::new().recursive(true).mode(0o700).create(dir) {
            Ok(()) => {}
            Err(e) if e.kind() == io::ErrorKind::AlreadyExists => {}
            Err(e) => return Err(e),
        }
        let meta = std::fs::symlink_metadata(dir)?;
        if !meta.is_dir() {
            return Err(io::Error::other(format!("{} is not a directory", dir.display())));
        }
        if meta.uid() != uid() || meta.mode() & 0o022 != 0 {
            return Err(io::Error::other(format!(
                "{} belongs to another user or others may write to it (mode {:o})",
                dir.display(),
                meta.mode() & 0o777
            )));
        }
        Ok(())
    }
}

#[cfg(not(unix))]
mod imp {
    use std::fs::File;
    use std::io;
    use std::path::Path;

    use super::Try;

    fn unsupported() -> io::Error {
        io::Error::new(io::ErrorKind::Unsupported, "port lock files need a Unix system")
    }

    pub fn open(_path: &Path) -> io::Result<File> {
        Err(unsupported())
    }

    pub fn try_lock(_file: &File) -> io::Result<Try> {
        Err(unsupported())
    }

    pub fn same_file(_file: &File, _path: &Path) -> bool {
        false
    }

    pub fn alive(_pid: u32) -> bool {
        false
    }

    pub fn is_motionlink(_pid: u32) -> Option<bool> {
        None
    }

    pub fn interrupt(_pid: u32) -> io::Result<()> {
        Err(unsupported())
    }

    pub fn uid() -> u32 {
        0
    }

    pub fn private_dir(_dir: &Path) -> io::Result<()> {
        Err(unsupported())
    }
}

/// Opens (creating it) the lock file at `path`.
pub fn open(path: &Path) -> std::io::Result<File> {
    imp::open(path)
}

/// Tries to lock `file` exclusively, without waiting.
pub fn try_lock(file: &File) -> std::io::Result<Try> {
    imp::try_lock(file)
}

/// True when `path` still names `file`.
pub fn same_file(file: &File, path: &Path) -> bool {
    imp::same_file(file, path)
}

/// True while process `pid` exists.
pub fn alive(pid: u32) -> bool {
    imp::alive(pid)
}

/// Whether process `pid` runs motionlink, where that can be told.
pub fn is_motionlink(pid: u32) -> Option<bool> {
    imp::is_motionlink(pid)
}

/// SIGINT to `pid`.
pub fn interrupt(pid: u32) -> std::io::Result<()> {
    imp::interrupt(pid)
}

/// The user's id (0 where there is none).
pub fn uid() -> u32 {
    imp::uid()
}

/// Makes `dir` private to this user, or says why it is not.
pub fn private_dir(dir: &Path) -> std::io::Result<()> {
    imp::private_dir(dir)
}
