//! Device profiles: what `motionlink probe --save` found out about a device, kept so that a later session on
//! the same port and the same device skips the probes.
//!
//! The file is `profiles.toml` beside `devices.toml` ([`config_dir`]): one table per port, device address (on
//! a bus) and identity, holding the capabilities the family's probe found:
//!
//! ```toml
//! [profile."scu:/dev/ttyUSB0:5f3a9c21"]
//! family = "scu"
//! port = "/dev/ttyUSB0"
//! identity = "SCU V2B3 ... | TLT ..."
//!
//! [profile."scu:/dev/ttyUSB0:5f3a9c21".capabilities]
//! grouping_indices = true
//! user_position_data = false
//! ```
//!
//! A session looks its device up ([`Profiles::lookup`]) with the identity the device gives (a cheap read):
//! the same identity seeds what the session knows, another identity leaves the profile unused with a
//! one-line notice. A profile only records what was probed: a capability the probe did not settle is absent
//! and is probed as without a profile.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

/// Why a profile file could not be read or written.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("{0}")]
pub struct ProfileError(pub String);

/// The configuration directory of motionlink: the directory of the file `MOTIONLINK_CONFIG` names when that
/// is set, else `motionlink` in the platform's configuration directory (`$XDG_CONFIG_HOME` or `~/.config`
/// on Linux and other Unix systems, `~/Library/Application Support` on macOS, `%APPDATA%` on Windows).
pub fn config_dir() -> Option<PathBuf> {
    if let Some(p) = std::env::var_os("MOTIONLINK_CONFIG") {
        let p = PathBuf::from(p);
        return Some(p.parent().map(Path::to_path_buf).unwrap_or_default());
    }
    platform_dir().map(|d| d.join("motionlink"))
}

/// The platform's configuration directory.
fn platform_dir() -> Option<PathBuf> {
    let home = || std::env::var_os("HOME").map(PathBuf::from);
    if cfg!(windows) {
        std::env::var_os("APPDATA").map(PathBuf::from)
    } else if cfg!(target_os = "macos") {
        home().map(|h| h.join("Library/Application Support"))
    } else {
        std::env::var_os("XDG_CONFIG_HOME").map(PathBuf::from).or_else(|| home().map(|h| h.join(".config")))
    }
}

/// The devices file: `MOTIONLINK_CONFIG`, else `devices.toml` in [`config_dir`].
pub fn devices_path() -> Option<PathBuf> {
    if let Some(p) = std::env::var_os("MOTIONLINK_CONFIG") {
        return Some(PathBuf::from(p));
    }
    config_dir().map(|d| d.join("devices.toml"))
}

/// The profiles file: `profiles.toml` in [`config_dir`] (beside `devices.toml`).
pub fn profiles_path() -> Option<PathBuf> {
    config_dir().map(|d| d.join("profiles.toml"))
}

/// One device's profile.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ProfileEntry {
    /// `scu`, `powercube` or `compax`.
    pub family: String,
    /// The port, as given to the probe.
    pub port: String,
    /// The module or drive address on a bus; absent for a whole unit.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub address: Option<u8>,
    /// What the device says it is (firmware, serial number, configuration), as its family reads it.
    pub identity: String,
    /// The baud rate it answered at, on a serial line.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub baud: Option<u32>,
    /// What was probed, as the family's capability type serialises it (absent: not settled).
    #[serde(default)]
    pub capabilities: toml::Table,
}

impl ProfileEntry {
    /// The key of this entry's table: `family:port[:address]:hash` of the identity.
    pub fn key(&self) -> String {
        let address = self.address.map(|a| format!(":{a}")).unwrap_or_default();
        format!("{}:{}{address}:{:08x}", self.family, self.port, fnv1a32(self.identity.as_bytes()))
    }

    /// The capabilities as the family's type `T`.
    pub fn capabilities<T: serde::de::DeserializeOwned>(&self) -> Result<T, ProfileError> {
        toml::Value::Table(self.capabilities.clone())
            .try_into()
            .map_err(|e| ProfileError(format!("the capabilities of profile {}: {e}", self.key())))
    }

    /// Sets the capabilities from the family's type.
    pub fn set_capabilities<T: Serialize>(&mut self, capabilities: &T) -> Result<(), ProfileError> {
        match toml::Value::try_from(capabilities) {
            Ok(toml::Value::Table(t)) => {
                self.capabilities = t;
                Ok(())
            }
            Ok(other) => Err(ProfileError(format!("capabilities serialise as {}, not a table", other.type_str()))),
            Err(e) => Err(ProfileError(format!("capabilities: {e}"))),
        }
    }
}

/// The 32-bit FNV-1a hash (a short, stable name for an identity in a key).
fn fnv1a32(bytes: &[u8]) -> u32 {
    bytes.iter().fold(0x811c_9dc5u32, |h, &b| (h ^ u32::from(b)).wrapping_mul(0x0100_0193))
}

/// What a lookup found for a device.
#[derive(Debug, Clone, PartialEq)]
pub enum Lookup {
    /// No profile for this port and address.
    None,
    /// The profile of this device: its reference (`<path>#<key>`) and its entry.
    Found {
        /// `<path>#<key>`, as `--json` results name it.
        reference: String,
        /// The profile.
        entry: ProfileEntry,
    },
    /// Profiles for this port and address exist, but for another identity: not used.
    Mismatch {
        /// One line saying so.
        notice: String,
    },
}

/// What a session made of the profiles when it opened: the profile it took (`<path>#<key>`, as `--json`
/// results name it) and the one-line notices about those it did not take (another identity, a file that
/// could not be read).
#[derive(Debug, Clone, Default, PartialEq, Eq, Serialize)]
pub struct ProfileUse {
    /// The profile used, if any.
    pub reference: Option<String>,
    /// Notices, one line each.
    pub notices: Vec<String>,
}

impl ProfileUse {
    /// Takes `lookup`'s answer: its capabilities go to `seed` (in the family's type `T`), its notice (or the
    /// reason its capabilities could not be read) to the notices.
    pub fn take<T: serde::de::DeserializeOwned>(&mut self, lookup: Lookup, seed: impl FnOnce(T)) {
        match lookup {
            Lookup::None => {}
            Lookup::Mismatch { notice } => self.notices.push(notice),
            Lookup::Found { reference, entry } => match entry.capabilities::<T>() {
                Ok(caps) => {
                    seed(caps);
                    self.reference = Some(reference);
                }
                Err(e) => self.notices.push(format!("{reference} not used: {e}")),
            },
        }
    }
}

/// The profiles of one file.
#[derive(Debug, Clone, PartialEq)]
pub struct Profiles {
    path: PathBuf,
    entries: BTreeMap<String, ProfileEntry>,
}

#[derive(Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct File {
    #[serde(default)]
    profile: BTreeMap<String, ProfileEntry>,
}

impl Profiles {
    /// No profiles, to be saved at `path`.
    pub fn empty(path: PathBuf) -> Profiles {
        Profiles { path, entries: BTreeMap::new() }
    }

    /// The profiles of the file at `path` (none when the file does not exist).
    pub fn load(path: &Path) -> Result<Profiles, ProfileError> {
        let text = match std::fs::read_to_string(path) {
            Ok(t) => t,
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(Profiles::empty(path.to_path_buf())),
            Err(e) => return Err(ProfileError(format!("cannot read {}: {e}", path.display()))),
        };
        let file: File = toml::from_str(&text).map_err(|e| ProfileError(format!("{}: {e}", path.display())))?;
        Ok(Profiles { path: path.to_path_buf(), entries: file.profile })
    }

    /// The profiles of the default file ([`profiles_path`]); `Ok(None)` when no configuration directory is
    /// known.
    pub fn load_default() -> Result<Option<Profiles>, ProfileError> {
        profiles_path().map(|p| Profiles::load(&p)).transpose()
    }

    /// The file.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Every profile, by key.
    pub fn entries(&self) -> &BTreeMap<String, ProfileEntry> {
        &self.entries
    }

    /// `<path>#<key>`.
    pub fn reference(&self, key: &str) -> String {
        format!("{}#{key}", self.path.display())
    }

    /// Adds `entry` (replacing one of the same key) and returns its reference.
    pub fn insert(&mut self, entry: ProfileEntry) -> String {
        let key = entry.key();
        self.entries.insert(key.clone(), entry);
        self.reference(&key)
    }

    /// True when some profile is kept for the device at `address` on `port` of `family` (whatever its
    /// identity): only then is the identity worth reading.
    pub fn has(&self, family: &str, port: &str, address: Option<u8>) -> bool {
        self.entries.values().any(|e| e.family == family && e.port == port && e.address == address)
    }

    /// The profile of the device at `address` on `port` of `family` that says it is `identity`.
    pub fn lookup(&self, family: &str, port: &str, address: Option<u8>, identity: &str) -> Lookup {
        let mut others = self.entries.values().filter(|e| e.family == family && e.port == port && e.address == address);
        let Some(first) = others.next() else { return Lookup::None };
        let mut candidates = std::iter::once(first).chain(others);
        if let Some(entry) = candidates.find(|e| e.identity == identity) {
            return Lookup::Found { reference: self.reference(&entry.key()), entry: entry.clone() };
        }
        let device = address.map(|a| format!(" (address {a})")).unwrap_or_default();
        Lookup::Mismatch {
            notice: format!(
                "profile of {port}{device} in {} not used: it was saved for {:?}, the device says {identity:?} \
                 (probe it again with `motionlink probe {family} --save`)",
                self.path.display(),
                first.identity
            ),
        }
    }

    /// Writes the file (creating its directory), with a comment that says what it is.
    pub fn save(&self) -> Result<(), ProfileError> {
        let file = File { profile: self.entries.clone() };
        let text = toml::to_string(&file).map_err(|e| ProfileError(format!("profiles: {e}")))?;
        let text = format!(
            "# Device profiles written by `motionlink probe --save`: what each device was found to do where the\n\
             # manuals leave it open. A session on the same port whose device gives the same identity skips those\n\
             # probes. Delete an entry (or the file) to probe again.\n\n{text}"
        );
        let shown = self.path.display();
        if let Some(dir) = self.path.parent().filter(|d| !d.as_os_str().is_empty()) {
            std::fs::create_dir_all(dir).map_err(|e| ProfileError(format!("cannot create {}: {e}", dir.display())))?;
        }
        let tmp = self.path.with_extension("toml.tmp");
        std::fs::write(&tmp, text).map_err(|e| ProfileError(format!("cannot write {}: {e}", tmp.display())))?;
        std::fs::rename(&tmp, &self.path).map_err(|e| ProfileError(format!("cannot write {shown}: {e}")))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[derive(Debug, Default, PartialEq, Serialize, Deserialize)]
    struct Caps {
        groups: Option<bool>,
        echo: Option<String>,
    }

    fn entry(port: &str, address: Option<u8>, identity: &str) -> ProfileEntry {
        ProfileEntry {
            family: "scu".into(),
            port: port.into(),
            address,
            identity: identity.into(),
            baud: Some(38_400),
            capabilities: toml::Table::new(),
        }
    }

    #[test]
    fn a_saved_profile_is_found_by_port_address_and_identity_and_keeps_only_what_was_probed() {
        let dir = std::env::temp_dir().join(format!("motionlink-profiles-{}", std::process::id()));
        let path = dir.join("sub/profiles.toml");
        let mut p = Profiles::load(&path).unwrap();
        assert!(p.entries().is_empty());
        let mut e = entry("/dev/ttyUSB0", None, "SCU V2B3 | TLT");
        e.set_capabilities(&Caps { groups: Some(false), echo: None }).unwrap();
        let reference = p.insert(e.clone());
        assert!(reference.starts_with(&format!("{}#scu:/dev/ttyUSB0:", path.display())), "{reference}");
        p.insert(entry("/dev/ttyUSB0", Some(3), "v4.6 serial 7"));
        p.save().unwrap();
        let text = std::fs::read_to_string(&path).unwrap();
        assert!(text.starts_with("# Device profiles") && !text.contains("echo"), "{text}");
        let back = Profiles::load(&path).unwrap();
        assert_eq!(back, p);
        match back.lookup("scu", "/dev/ttyUSB0", None, "SCU V2B3 | TLT") {
            Lookup::Found { reference: r, entry } => {
                assert_eq!(r, reference);
                assert_eq!(entry.capabilities::<Caps>().unwrap(), Caps { groups: Some(false), echo: None });
            }
            other => panic!("{other:?}"),
        }
        match back.lookup("scu", "/dev/ttyUSB0", None, "SCU V2B4 | TLT") {
            Lookup::Mismatch { notice } => assert!(notice.contains("V2B3") && notice.contains("V2B4"), "{notice}"),
            other => panic!("{other:?}"),
        }
        assert_eq!(back.lookup("scu", "/dev/ttyUSB1", None, "SCU V2B3 | TLT"), Lookup::None);
        assert_eq!(back.lookup("compax", "/dev/ttyUSB0", None, "SCU V2B3 | TLT"), Lookup::None);
        assert!(matches!(back.lookup("scu", "/dev/ttyUSB0", Some(3), "v4.6 serial 7"), Lookup::Found { .. }));
        std::fs::remove_dir_all(dir).unwrap();
    }

    #[test]
    fn a_broken_file_is_an_error_naming_it() {
        let path = std::env::temp_dir().join(format!("motionlink-broken-profiles-{}.toml", std::process::id()));
        std::fs::write(&path, "[profile.x]\nfamily = 3\n").unwrap();
        let e = Profiles::load(&path).unwrap_err();
        assert!(e.0.contains(&path.display().to_string()), "{e}");
        std::fs::remove_file(path).unwrap();
    }
}
