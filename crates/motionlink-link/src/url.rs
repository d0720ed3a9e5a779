//! Port names as users write them: `/dev/ttyUSB0`, `COM3`, `tcp://HOST:PORT`, `sim`, `socketcan://can0`,
//! `slcan:///dev/ttyACM0`.

use std::fmt;
use std::str::FromStr;

use crate::can::{SlcanBitrate, SlcanLink};
use crate::clock::SharedClock;
use crate::link::{Link, LinkError, SerialSettings};
use crate::serial::SerialLink;
use crate::tcp::TcpLink;

/// Where a device is, parsed from the `--port` argument.
///
/// ```
/// use motionlink_link::url::PortUrl;
/// assert_eq!("tcp://127.0.0.1:4000".parse::<PortUrl>().unwrap(),
///            PortUrl::Tcp { host: "127.0.0.1".into(), port: 4000 });
/// assert_eq!("COM3".parse::<PortUrl>().unwrap(), PortUrl::Serial("COM3".into()));
/// assert!("tcp://nohost".parse::<PortUrl>().is_err());
/// ```
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum PortUrl {
    /// A serial device path: `/dev/ttyUSB0`, `COM3`.
    Serial(String),
    /// A TCP byte stream: a serial gateway or a `motionlink sim` server.
    Tcp {
        /// Host name or address.
        host: String,
        /// TCP port.
        port: u16,
    },
    /// An emulator started in-process.
    Sim,
    /// A SocketCAN network interface (Linux): `socketcan://can0`.
    SocketCan(String),
    /// A serial CAN adapter speaking SLCAN: `slcan:///dev/ttyACM0` (the path of its serial port), or
    /// `slcan://tcp://HOST:PORT` (an adapter behind a TCP port); opened by [`open_slcan`].
    Slcan(String),
}

impl PortUrl {
    /// True for the CAN kinds of port.
    pub fn is_can(&self) -> bool {
        matches!(self, PortUrl::SocketCan(_) | PortUrl::Slcan(_))
    }

    /// Opens a byte-stream port (serial or TCP). `Sim` and CAN ports are not byte streams and are refused.
    pub fn open_byte_link(&self, settings: SerialSettings) -> Result<Box<dyn Link>, LinkError> {
        match self {
            PortUrl::Serial(path) => Ok(Box::new(SerialLink::open(path, settings)?)),
            PortUrl::Tcp { host, port } => Ok(Box::new(TcpLink::connect(host, *port)?)),
            other => Err(LinkError::InvalidPort {
                port: other.to_string(),
                reason: "not a byte-stream port (expected a serial device or tcp://HOST:PORT)".into(),
            }),
        }
    }
}

/// Opens the SLCAN adapter of a `slcan://PATH` port as a CAN link at `bitrate`. `PATH` is the adapter's serial
/// device (`slcan:///dev/ttyACM0`; no modem lines are raised, an adapter needs none), or `tcp://HOST:PORT` for an
/// adapter behind a TCP port (a serial gateway, or `motionlink sim powercube --slcan --tcp ...`, whose port is
/// `slcan://tcp://127.0.0.1:PORT`).
///
/// ```no_run
/// use motionlink_link::can::SlcanBitrate;
/// use motionlink_link::url::open_slcan;
/// let bus = open_slcan("/dev/ttyACM0", motionlink_link::RealClock::shared(), SlcanBitrate::from_bps(1_000_000).unwrap())?;
/// # Ok::<(), motionlink_link::LinkError>(())
/// ```
pub fn open_slcan(
    path: &str,
    clock: SharedClock,
    bitrate: SlcanBitrate,
) -> Result<SlcanLink<Box<dyn Link>>, LinkError> {
    let line: Box<dyn Link> = match path.parse::<PortUrl>()? {
        PortUrl::Tcp { host, port } => Box::new(TcpLink::connect(&host, port)?),
        PortUrl::Serial(device) => {
            Box::new(SerialLink::open(&device, SerialSettings { dtr_rts_on: false, ..SerialSettings::new(115_200) })?)
        }
        other => {
            return Err(LinkError::InvalidPort {
                port: format!("slcan://{other}"),
                reason: "an SLCAN adapter is on a serial device or behind tcp://HOST:PORT".into(),
            })
        }
    };
    SlcanLink::open(line, clock, bitrate)
}

impl FromStr for PortUrl {
    type Err = LinkError;

    fn from_str(s: &str) -> Result<Self, LinkError> {
        let invalid = |reason: &str| LinkError::InvalidPort { port: s.to_string(), reason: reason.to_string() };
        let s_trim = s.trim();
        if s_trim.is_empty() {
            return Err(invalid("empty port name"));
        }
        if s_trim == "sim" {
            return Ok(PortUrl::Sim);
        }
        let Some((scheme, rest)) = s_trim.split_once("://") else {
            return Ok(PortUrl::Serial(s_trim.to_string()));
        };
        match scheme {
            "tcp" => {
                let (host, port) = rest.rsplit_once(':').ok_or_else(|| invalid("expected tcp://HOST:PORT"))?;
                // An IPv6 address in brackets: both of them, or neither.
                let host = match (host.strip_prefix('['), host.ends_with(']')) {
                    (Some(inner), true) => &inner[..inner.len() - 1],
                    (None, false) => host,
                    _ => return Err(invalid("unbalanced brackets: an IPv6 host is tcp://[ADDRESS]:PORT")),
                };
                if host.is_empty() || host.contains(['[', ']']) {
                    return Err(invalid("missing host in tcp://HOST:PORT"));
                }
                let port: u16 = port.parse().map_err(|_| invalid("the TCP port must be a number 1..65535"))?;
                if port == 0 {
                    return Err(invalid("the TCP port must be a number 1..65535"));
                }
                Ok(PortUrl::Tcp { host: host.to_string(), port })
            }
            "serial" if !rest.is_empty() => Ok(PortUrl::Serial(rest.to_string())),
            "socketcan" if !rest.is_empty() && !rest.contains('/') => Ok(PortUrl::SocketCan(rest.to_string())),
            "socketcan" => Err(invalid("expected socketcan://INTERFACE, such as socketcan://can0")),
            "slcan" if !rest.is_empty() => Ok(PortUrl::Slcan(rest.to_string())),
            "slcan" | "serial" => Err(invalid("missing device path")),
            _ => Err(invalid(
                "unknown scheme (known: tcp://, socketcan://, slcan://, serial://, or a device path, or sim)",
            )),
        }
    }
}

impl fmt::Display for PortUrl {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            PortUrl::Serial(p) => f.write_str(p),
            PortUrl::Tcp { host, port } if host.contains(':') => write!(f, "tcp://[{host}]:{port}"),
            PortUrl::Tcp { host, port } => write!(f, "tcp://{host}:{port}"),
            PortUrl::Sim => f.write_str("sim"),
            PortUrl::SocketCan(i) => write!(f, "socketcan://{i}"),
            PortUrl::Slcan(p) => write!(f, "slcan://{p}"),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_every_kind() {
        let cases = [
            ("/dev/ttyUSB0", PortUrl::Serial("/dev/ttyUSB0".into())),
            ("COM3", PortUrl::Serial("COM3".into())),
            ("serial:///dev/ttyS0", PortUrl::Serial("/dev/ttyS0".into())),
            ("tcp://localhost:2000", PortUrl::Tcp { host: "localhost".into(), port: 2000 }),
            ("tcp://[::1]:2000", PortUrl::Tcp { host: "::1".into(), port: 2000 }),
            ("sim", PortUrl::Sim),
            ("socketcan://can0", PortUrl::SocketCan("can0".into())),
            ("slcan:///dev/ttyACM0", PortUrl::Slcan("/dev/ttyACM0".into())),
        ];
        for (text, want) in cases {
            let got: PortUrl = text.parse().unwrap();
            assert_eq!(got, want, "{text}");
            assert_eq!(got.to_string().parse::<PortUrl>().unwrap(), want, "round trip of {text}");
        }
    }

    #[test]
    fn rejects_bad_ports_with_a_reason() {
        for bad in [
            "",
            "tcp://host",
            "tcp://:80",
            "tcp://h:0",
            "tcp://h:99999",
            "udp://h:1",
            "socketcan://",
            "slcan://",
            "tcp://[::1:1",
            "tcp://::1]:1",
            "tcp://[]:1",
        ] {
            let err = bad.parse::<PortUrl>().unwrap_err();
            assert!(matches!(err, LinkError::InvalidPort { .. }), "{bad}: {err}");
        }
    }

    #[test]
    fn sim_and_can_are_not_byte_links() {
        assert!(PortUrl::Sim.open_byte_link(SerialSettings::new(38_400)).is_err());
        assert!(PortUrl::SocketCan("can0".into()).open_byte_link(SerialSettings::new(38_400)).is_err());
    }
}
