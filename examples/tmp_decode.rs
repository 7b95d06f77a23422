fn main() {
    let bytes = std::fs::read(std::env::args().nth(1).unwrap()).unwrap();
    for _ in 0..5 {
        let t = std::time::Instant::now();
        let b = tracer::bundle::Bundle::decode(&bytes).unwrap();
        println!("{:?} {}", t.elapsed(), b.name);
    }
}
