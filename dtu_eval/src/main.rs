//! `dtu-eval`: the Chamfer evaluation command line.

fn main() {
    println!("dtu-eval {}", env!("CARGO_PKG_VERSION"));
}
