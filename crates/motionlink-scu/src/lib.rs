//! Ewellix / Schaeffler SCU control unit over RS232.
#![warn(missing_docs)]

pub mod client;
pub mod describe;
pub mod model;
pub mod sim;
pub mod value;
pub mod wire;
