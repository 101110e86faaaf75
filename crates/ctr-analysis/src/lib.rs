//! The std layer shared by the CLI and the Python wheel: file formats, batch solving,
//! inverse kinematics, fitting and diagnosis.
