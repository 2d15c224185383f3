//! The `morphoid` command-line tool.

fn main() {
    println!("morphoid");
}
