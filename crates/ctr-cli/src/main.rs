//! `ctr-cli`: batch kinematics, diagnosis and hardware runs for concentric tube robots.
fn main() {}
