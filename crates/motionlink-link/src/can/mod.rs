//! CAN frames and CAN links: SocketCAN, SLCAN serial adapters, and an in-memory bus with bit-time pacing.
//! (Built with the PowerCube family.)
