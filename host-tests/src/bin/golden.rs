//! Prints the core's golden vectors on the host (compare with the QEMU Cortex-M4 run).
fn main() {
    let mut s = String::new();
    beamshaper::golden::write_golden(&mut s).expect("formatting into a String");
    print!("{s}");
}
