//! An emulated SLCAN adapter: serves a [`CanEmulator`] on a byte stream, as a USB-CAN adapter does.

use super::{encode_frame, SlcanBitrate, SlcanDecoder, SlcanError, SlcanMessage, BELL, CR, MAX_LINE};
use crate::can::{CanEmulator, CanFrame};
use crate::clock::Timestamp;
use crate::emulator::Emulator;

/// Serves a [`CanEmulator`] on a byte stream as a serial SLCAN adapter would: setup commands answered, frames
/// from the host handed to the device while the channel is open, the device's frames sent as `t` lines.
///
/// Frames sent by the host while the channel is closed are refused with a bell, as adapters do;
/// [`SlcanAdapter::refuse_next`] makes it refuse frames while open (a full transmit queue, a controller gone
/// bus off).
pub struct SlcanAdapter<E> {
    device: E,
    decoder: SlcanDecoder,
    open: bool,
    timestamps: bool,
    bitrate: Option<SlcanBitrate>,
    frames: Vec<CanFrame>,
    refuse: u64,
}

impl<E: CanEmulator> SlcanAdapter<E> {
    /// An adapter with its channel closed, in front of `device`.
    pub fn new(device: E) -> Self {
        SlcanAdapter {
            device,
            decoder: SlcanDecoder::new(),
            open: false,
            timestamps: false,
            bitrate: None,
            frames: Vec::new(),
            refuse: 0,
        }
    }

    /// Refuses the next `count` frames from the host with a bell, as an adapter whose transmit queue is full
    /// or whose controller is bus off does (a test hook).
    pub fn refuse_next(&mut self, count: u64) {
        self.refuse = count;
    }

    /// The device behind the adapter.
    pub fn device(&self) -> &E {
        &self.device
    }

    /// The device behind the adapter.
    pub fn device_mut(&mut self) -> &mut E {
        &mut self.device
    }

    /// True while the channel is open.
    pub fn is_open(&self) -> bool {
        self.open
    }

    /// The bit rate the host set, if any.
    pub fn bitrate(&self) -> Option<SlcanBitrate> {
        self.bitrate
    }

    fn emit_frames(&mut self, now: Timestamp, out: &mut Vec<u8>) {
        let mut line = [0u8; MAX_LINE];
        for frame in self.frames.drain(..) {
            if !self.open {
                continue;
            }
            let n = encode_frame(&frame, &mut line);
            if self.timestamps {
                let ms = (now.since_origin().as_millis() % 60_000) as u16;
                out.extend_from_slice(&line[..n - 1]);
                out.extend_from_slice(format!("{ms:04X}\r").as_bytes());
            } else {
                out.extend_from_slice(&line[..n]);
            }
        }
    }

    fn handle(&mut self, now: Timestamp, msg: Result<SlcanMessage, SlcanError>, out: &mut Vec<u8>) {
        match msg {
            Ok(SlcanMessage::Frame { frame, .. }) => {
                if !self.open {
                    out.push(BELL);
                    return;
                }
                if self.refuse > 0 {
                    self.refuse -= 1;
                    out.push(BELL);
                    return;
                }
                out.extend_from_slice(if frame.is_extended() { b"Z\r" } else { b"z\r" });
                self.device.receive(now, &frame, &mut self.frames);
                self.emit_frames(now, out);
            }
            Ok(SlcanMessage::Bitrate(rate)) if !self.open => {
                self.bitrate = Some(rate);
                out.push(CR);
            }
            Ok(SlcanMessage::Open | SlcanMessage::ListenOnly) if !self.open => {
                self.open = true;
                out.push(CR);
            }
            Ok(SlcanMessage::Close) if self.open => {
                self.open = false;
                out.push(CR);
            }
            Ok(SlcanMessage::Timestamps(on)) if !self.open => {
                self.timestamps = on;
                out.push(CR);
            }
            Ok(SlcanMessage::Version(None)) => out.extend_from_slice(b"V1013\r"),
            Ok(SlcanMessage::Serial(None)) => out.extend_from_slice(b"NML01\r"),
            Ok(SlcanMessage::Status(None)) if self.open => out.extend_from_slice(b"F00\r"),
            Ok(SlcanMessage::Ok) => {}
            _ => out.push(BELL),
        }
    }
}

impl<E: CanEmulator> Emulator for SlcanAdapter<E> {
    fn receive(&mut self, now: Timestamp, bytes: &[u8], out: &mut Vec<u8>) {
        for &b in bytes {
            if let Some(msg) = self.decoder.push(b) {
                self.handle(now, msg, out);
            }
        }
    }

    fn advance(&mut self, now: Timestamp, out: &mut Vec<u8>) {
        self.device.advance(now, &mut self.frames);
        self.emit_frames(now, out);
    }

    fn next_wakeup(&self) -> Option<Timestamp> {
        self.device.next_wakeup()
    }

    /// The host closed the serial port: a command line it left unfinished is dropped. The CAN channel stays
    /// open, as on a real adapter, and the modules behind it run on.
    fn connection_closed(&mut self, _now: Timestamp) {
        self.decoder.reset();
    }

    fn take_events(&mut self) -> Vec<String> {
        self.device.take_events()
    }
}
