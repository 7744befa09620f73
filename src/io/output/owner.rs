//! Who wrote a temporary file, and whether that writer has certainly ended (see the
//! documentation of [`super`]): the owner's host, PID namespace and process id, probed in
//! `/proc` when it is this host's and this namespace's, judged by its lease otherwise; and
//! the lease itself, refreshed by a background thread while the process runs.

use std::path::{Path, PathBuf};
use std::sync::{Mutex, OnceLock};
use std::time::SystemTime;

/// The writer of a temporary file or journal, as its name records it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct Owner {
    /// Hash of the host's identity; None: unknown (not recorded, or unreadable there).
    pub host: Option<u32>,
    /// Inode of the PID namespace; 0 unknown.
    pub pid_namespace: u64,
    pub pid: u32,
}

impl std::fmt::Display for Owner {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let me = Owner::this_process();
        if self.host.is_some() && self.host == me.host {
            if self.pid_namespace == me.pid_namespace {
                write!(f, "process {} on this host", self.pid)
            } else {
                write!(
                    f,
                    "process {} in another PID namespace of this host",
                    self.pid
                )
            }
        } else {
            match self.host {
                Some(h) => write!(f, "process {} on host {h:08x}", self.pid),
                None => write!(f, "process {} on an unknown host", self.pid),
            }
        }
    }
}

impl Owner {
    /// This process.
    pub fn this_process() -> Owner {
        static ME: OnceLock<Owner> = OnceLock::new();
        *ME.get_or_init(|| Owner {
            host: host_identity().map(|text| fnv1a_32(text.as_bytes())),
            pid_namespace: pid_namespace(),
            pid: std::process::id(),
        })
    }

    /// `<host>-<pidns>-<pid>` for file names (`00000000` for an unknown host).
    pub fn token(&self) -> String {
        format!(
            "{:08x}-{}-{}",
            self.host.unwrap_or(0),
            self.pid_namespace,
            self.pid
        )
    }

    /// Reads [`Owner::token`], or a bare `<pid>` (names written before owners had a host:
    /// the host is then unknown).
    pub fn parse(token: &str) -> Option<Owner> {
        let parts: Vec<&str> = token.split('-').collect();
        match parts.as_slice() {
            [pid] => Some(Owner {
                host: None,
                pid_namespace: 0,
                pid: pid.parse().ok()?,
            }),
            [host, ns, pid] if host.len() == 8 => {
                let host = u32::from_str_radix(host, 16).ok()?;
                Some(Owner {
                    host: (host != 0).then_some(host),
                    pid_namespace: ns.parse().ok()?,
                    pid: pid.parse().ok()?,
                })
            }
            _ => None,
        }
    }

    /// True when this owner can be looked up in the local `/proc`: this host, this PID
    /// namespace, and a `/proc` that shows this namespace.
    fn can_be_probed(&self) -> bool {
        let me = Owner::this_process();
        self.host.is_some()
            && self.host == me.host
            && self.pid_namespace != 0
            && self.pid_namespace == me.pid_namespace
            && proc_shows_this_namespace()
    }

    /// True when the writer of the file at `path` has certainly ended: probed in `/proc`
    /// when it can be ([`Owner::can_be_probed`]: gone, or a zombie), else its lease on
    /// `path` has run out (not modified for [`super::LEASE_PERIOD`]).
    pub fn has_ended(&self, path: &Path) -> bool {
        if self.can_be_probed() {
            self.pid != std::process::id() && process_has_ended(self.pid)
        } else {
            lease_has_run_out(path, SystemTime::now())
        }
    }
}

/// The host's identity: `/etc/machine-id` (else the kernel's boot id) and the host name.
/// None when neither an id nor a name can be read.
fn host_identity() -> Option<String> {
    let read = |p: &str| {
        std::fs::read_to_string(p)
            .ok()
            .map(|t| t.trim().to_string())
            .filter(|t| !t.is_empty())
    };
    let id = read("/etc/machine-id").or_else(|| read("/proc/sys/kernel/random/boot_id"));
    let name = read("/proc/sys/kernel/hostname")
        .or_else(|| read("/etc/hostname"))
        .or_else(|| std::env::var("HOSTNAME").ok().filter(|h| !h.is_empty()));
    match (id, name) {
        (None, None) => None,
        (id, name) => Some(format!(
            "{}\n{}",
            id.unwrap_or_default(),
            name.unwrap_or_default()
        )),
    }
}

/// The inode of this process's PID namespace (`pid:[4026531836]`); 0 where unknown.
fn pid_namespace() -> u64 {
    std::fs::read_link("/proc/self/ns/pid")
        .ok()
        .and_then(|l| {
            let l = l.to_string_lossy().into_owned();
            l.strip_prefix("pid:[")?.strip_suffix(']')?.parse().ok()
        })
        .unwrap_or(0)
}

/// True when `/proc` is mounted for this PID namespace: `/proc/self` names this process's
/// id. (In a namespace made without remounting `/proc`, it shows the parent's ids.)
fn proc_shows_this_namespace() -> bool {
    static SHOWS: OnceLock<bool> = OnceLock::new();
    *SHOWS.get_or_init(|| {
        std::fs::read_link("/proc/self")
            .ok()
            .and_then(|l| l.to_string_lossy().parse::<u32>().ok())
            == Some(std::process::id())
    })
}

/// True when process `pid` of this namespace has ended: no `/proc/<pid>`, or a zombie
/// (state `Z`, or `X` dead) that only waits for its parent to reap it.
pub(crate) fn process_has_ended(pid: u32) -> bool {
    let Ok(stat) = std::fs::read_to_string(format!("/proc/{pid}/stat")) else {
        return !Path::new(&format!("/proc/{pid}")).exists();
    };
    // `pid (command) state …`: the command may hold spaces and parentheses
    let state = stat
        .rfind(')')
        .and_then(|i| stat[i + 1..].split_whitespace().next());
    matches!(state, Some("Z" | "X"))
}

/// True when the file at `path` has not been modified for [`super::LEASE_PERIOD`] before
/// `now`. A file that cannot be read, or a modification time in the future, is not stale.
pub(crate) fn lease_has_run_out(path: &Path, now: SystemTime) -> bool {
    std::fs::symlink_metadata(path)
        .and_then(|m| m.modified())
        .ok()
        .and_then(|modified| now.duration_since(modified).ok())
        .is_some_and(|age| age > super::LEASE_PERIOD)
}

/// The files whose lease this process holds.
fn leased() -> &'static Mutex<Vec<PathBuf>> {
    static LEASED: Mutex<Vec<PathBuf>> = Mutex::new(Vec::new());
    &LEASED
}

/// Holds the lease on `path` (a temporary or journal of this process): the refresher thread,
/// started by the first lease, touches it every [`super::LEASE_REFRESH`] until released.
pub(crate) fn lease_taken(path: &Path) {
    static REFRESHER: std::sync::Once = std::sync::Once::new();
    leased()
        .lock()
        .unwrap_or_else(|e| e.into_inner())
        .push(path.to_path_buf());
    REFRESHER.call_once(|| {
        let _ = std::thread::Builder::new()
            .name("musculo-lease".into())
            .spawn(|| {
                loop {
                    std::thread::sleep(super::LEASE_REFRESH);
                    refresh_leases(SystemTime::now());
                }
            });
    });
}

/// Releases the lease on `path` (renamed or removed).
pub(crate) fn lease_released(path: &Path) {
    let mut held = leased().lock().unwrap_or_else(|e| e.into_inner());
    if let Some(i) = held.iter().position(|p| p == path) {
        held.swap_remove(i);
    }
}

/// Sets the modification time of every leased file to `now`.
fn refresh_leases(now: SystemTime) {
    let held = leased().lock().unwrap_or_else(|e| e.into_inner());
    for path in held.iter() {
        if let Ok(f) = std::fs::OpenOptions::new().write(true).open(path) {
            let _ = f.set_modified(now);
        }
    }
}

/// FNV-1a, 32 bits.
fn fnv1a_32(bytes: &[u8]) -> u32 {
    let mut h: u32 = 0x811c_9dc5;
    for &b in bytes {
        h = (h ^ b as u32).wrapping_mul(0x0100_0193);
    }
    h
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tokens_round_trip_and_bare_pids_have_an_unknown_host() {
        let me = Owner::this_process();
        assert_eq!(Owner::parse(&me.token()), Some(me));
        let old = Owner::parse("1234").unwrap();
        assert_eq!((old.host, old.pid_namespace, old.pid), (None, 0, 1234));
        assert_eq!(Owner::parse("zz-1-2"), None);
        assert_eq!(Owner::parse("0000000a-x-2"), None);
    }

    #[test]
    fn this_process_is_alive_and_a_reaped_child_has_ended() {
        if !proc_shows_this_namespace() {
            return; // no /proc of this namespace: nothing can be probed here
        }
        assert!(!process_has_ended(std::process::id()));
        let mut child = std::process::Command::new("true").spawn().unwrap();
        child.wait().unwrap();
        assert!(process_has_ended(child.id()));
    }

    #[test]
    fn a_killed_child_not_yet_reaped_has_ended() {
        if !proc_shows_this_namespace() {
            return;
        }
        let mut child = std::process::Command::new("sleep")
            .arg("30")
            .spawn()
            .unwrap();
        assert!(!process_has_ended(child.id()));
        child.kill().unwrap();
        // a zombie until waited for
        let deadline = std::time::Instant::now() + std::time::Duration::from_secs(5);
        while !process_has_ended(child.id()) && std::time::Instant::now() < deadline {
            std::thread::sleep(std::time::Duration::from_millis(10));
        }
        assert!(
            process_has_ended(child.id()),
            "a zombie is a process that has ended"
        );
        assert!(Path::new(&format!("/proc/{}", child.id())).exists());
        child.wait().unwrap();
    }

    #[test]
    fn a_lease_runs_out_only_after_the_lease_period() {
        let p = std::env::temp_dir().join(format!("musculo-lease-{}", std::process::id()));
        std::fs::write(&p, "x").unwrap();
        let now = SystemTime::now();
        assert!(!lease_has_run_out(&p, now));
        let later = now + super::super::LEASE_PERIOD + std::time::Duration::from_secs(5);
        assert!(lease_has_run_out(&p, later));
        // refreshed: fresh again at that later time
        lease_taken(&p);
        refresh_leases(later);
        assert!(!lease_has_run_out(&p, later));
        lease_released(&p);
        let _ = std::fs::remove_file(&p);
    }
}
