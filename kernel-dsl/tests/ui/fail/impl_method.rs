#[kernel_dsl::kernel]
pub mod k {
    pub struct Disk {
        pub radius: f32,
    }

    impl Disk {
        pub fn area(&self) -> f32 {
            3.0 * self.radius * self.radius
        }
    }
}

fn main() {}
