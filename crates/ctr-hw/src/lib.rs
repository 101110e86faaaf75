//! Serial link to the servo controller (Dynamixel Protocol 2.0). Work in progress.
