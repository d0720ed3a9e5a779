//! The topics of a gateway, a public interface: `motionlink/<gateway>/status`,
//! `motionlink/<gateway>/<device>/state`, `.../cmd`, `.../events`.

/// The first level of every topic.
pub const ROOT: &str = "motionlink";

/// Refuses a name that cannot be one topic level: empty, or with `/`, `+`, `#` or a control character.
pub fn check_name(name: &str) -> Result<(), String> {
    if name.is_empty() {
        return Err("empty".into());
    }
    if let Some(c) = name.chars().find(|c| matches!(c, '/' | '+' | '#') || c.is_control()) {
        return Err(format!("{c:?} cannot be in a topic level (no /, + or #)"));
    }
    Ok(())
}

/// True for a topic of the gateways' tree: `motionlink` and everything under `motionlink/` (every gateway's
/// `status`, and its devices' `state`, `cmd` and `events`). The gateway publishes no reply there: a reply
/// would pose as a gateway's status, a device's state, an event or a request.
pub fn in_tree(topic: &str) -> bool {
    topic.strip_prefix(ROOT).is_some_and(|rest| rest.is_empty() || rest.starts_with('/'))
}

/// The topics of one gateway.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Topics {
    gateway: String,
}

impl Topics {
    /// The topics of the gateway `name` (a checked topic level: [`check_name`]).
    pub fn new(name: &str) -> Topics {
        Topics { gateway: name.to_string() }
    }

    /// `motionlink/<gateway>/status`: retained `online` / `offline`.
    pub fn status(&self) -> String {
        format!("{ROOT}/{}/status", self.gateway)
    }

    /// `motionlink/<gateway>/<device>/state`: retained JSON.
    pub fn state(&self, device: &str) -> String {
        format!("{ROOT}/{}/{device}/state", self.gateway)
    }

    /// `motionlink/<gateway>/<device>/cmd`: requests.
    pub fn cmd(&self, device: &str) -> String {
        format!("{ROOT}/{}/{device}/cmd", self.gateway)
    }

    /// `motionlink/<gateway>/<device>/events`.
    pub fn events(&self, device: &str) -> String {
        format!("{ROOT}/{}/{device}/events", self.gateway)
    }

    /// What the gateway subscribes to: every device's `cmd`.
    pub fn all_cmd(&self) -> String {
        format!("{ROOT}/{}/+/cmd", self.gateway)
    }

    /// The device a `cmd` topic of this gateway names.
    pub fn device_of_cmd<'t>(&self, topic: &'t str) -> Option<&'t str> {
        let rest = topic.strip_prefix(ROOT)?.strip_prefix('/')?.strip_prefix(self.gateway.as_str())?;
        let device = rest.strip_prefix('/')?.strip_suffix("/cmd")?;
        (!device.is_empty() && !device.contains('/')).then_some(device)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn topic_names_are_the_public_interface() {
        let t = Topics::new("wing-a");
        assert_eq!(t.status(), "motionlink/wing-a/status");
        assert_eq!(t.state("bed1"), "motionlink/wing-a/bed1/state");
        assert_eq!(t.cmd("bed1"), "motionlink/wing-a/bed1/cmd");
        assert_eq!(t.events("bed1"), "motionlink/wing-a/bed1/events");
        assert_eq!(t.all_cmd(), "motionlink/wing-a/+/cmd");
        assert_eq!(t.device_of_cmd("motionlink/wing-a/bed1/cmd"), Some("bed1"));
        for other in ["motionlink/wing-b/bed1/cmd", "motionlink/wing-a/bed1/state", "motionlink/wing-a/a/b/cmd", "x"] {
            assert_eq!(t.device_of_cmd(other), None, "{other}");
        }
    }

    #[test]
    fn the_gateways_tree_is_motionlink_and_below() {
        for mine in
            ["motionlink", "motionlink/", "motionlink/wing-a/status", "motionlink/wing-b/bed1/cmd", "motionlink//x"]
        {
            assert!(in_tree(mine), "{mine}");
        }
        for other in ["motionlink-reply/nurse/a", "motionlinks/a", "me/r", "x/motionlink/a", "Motionlink/a", ""] {
            assert!(!in_tree(other), "{other}");
        }
    }

    #[test]
    fn names_are_single_topic_levels() {
        assert!(check_name("bed-1.left").is_ok());
        for bad in ["", "a/b", "a+", "#", "a\nb"] {
            assert!(check_name(bad).is_err(), "{bad:?}");
        }
    }
}
