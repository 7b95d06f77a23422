#[kernel_dsl::kernel]
mod missing;

fn main() {}
