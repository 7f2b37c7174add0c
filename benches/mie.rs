//! Mie solver benchmarks (work in progress).
fn main() {}
