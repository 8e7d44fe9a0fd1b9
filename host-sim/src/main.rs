//! host-sim: runs the odocal library against a simulated robot.
fn main() {}
