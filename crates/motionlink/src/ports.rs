//! `motionlink list-ports`: the serial ports and CAN interfaces of this machine.

use std::io::Write;

use crate::common::{self, CliError};

/// One port: the `--port` to give, its kind, and what is known about it (a `--json` line).
#[derive(serde::Serialize)]
struct Found {
    port: String,
    kind: &'static str,
    about: String,
}

fn serial_ports() -> Vec<Found> {
    let ports = serialport::available_ports().unwrap_or_default();
    ports
        .into_iter()
        .map(|p| {
            let about = match p.port_type {
                serialport::SerialPortType::UsbPort(u) => format!(
                    "USB {:04x}:{:04x}{}{}",
                    u.vid,
                    u.pid,
                    u.manufacturer.map(|m| format!(" {m}")).unwrap_or_default(),
                    u.product.map(|m| format!(" {m}")).unwrap_or_default()
                ),
                serialport::SerialPortType::PciPort => "PCI".into(),
                serialport::SerialPortType::BluetoothPort => "Bluetooth".into(),
                serialport::SerialPortType::Unknown => String::new(),
            };
            Found { port: p.port_name, kind: "serial", about }
        })
        .collect()
}

/// CAN network interfaces (type 280, ARPHRD_CAN, in sysfs).
fn can_interfaces() -> Vec<Found> {
    let mut found = Vec::new();
    let Ok(dir) = std::fs::read_dir("/sys/class/net") else { return found };
    for entry in dir.flatten() {
        let name = entry.file_name().to_string_lossy().to_string();
        let kind = std::fs::read_to_string(entry.path().join("type")).unwrap_or_default();
        if kind.trim() == "280" {
            let state = std::fs::read_to_string(entry.path().join("operstate")).unwrap_or_default();
            found.push(Found {
                port: format!("socketcan://{name}"),
                kind: "can",
                about: format!("state {}", state.trim()),
            });
        }
    }
    found.sort_by(|a, b| a.port.cmp(&b.port));
    found
}

/// `motionlink list-ports`
pub fn list(json: bool) -> Result<(), CliError> {
    let mut all = serial_ports();
    all.extend(can_interfaces());
    let mut out = std::io::stdout().lock();
    if json {
        // A listing: one object per port (JSON Lines); none found prints nothing.
        for f in &all {
            common::print_json(&mut out, f)?;
        }
        return Ok(());
    }
    if all.is_empty() {
        writeln!(
            out,
            "no serial port or CAN interface found (a `motionlink sim` emulator is reachable as tcp://HOST:PORT)"
        )?;
        return Ok(());
    }
    let rows: Vec<common::Row> =
        all.iter().map(|f| (f.port.clone(), format!("{} {}", f.kind, f.about).trim().to_string())).collect();
    common::print_table(&mut out, &rows)
}
