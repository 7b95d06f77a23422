//! Prints the mean radiance of the Cornell box for each strategy (a quick consistency check).
use tracer::backend::cpu::CpuRenderer;
use tracer::pack::{pack, RenderSettings, Strategy};

fn main() {
    let mut scene = tracer::scene::cornell_box();
    let depth: u32 = std::env::args().nth(1).map_or(8, |a| a.parse().unwrap());
    if std::env::args().nth(2).as_deref() == Some("noceil") {
        scene.triangles.retain(|t| !(t.material == 1));
    }
    if std::env::args().nth(2).as_deref() == Some("onlyfloor") {
        scene.triangles.retain(|t| t.material == 0 || t.material == 7);
    }
    if std::env::args().nth(2).as_deref() == Some("lowlamp") {
        for t in scene.triangles.iter_mut().filter(|t| t.material == 7) {
            for p in &mut t.positions {
                p.y = 1.8;
            }
        }
    }
    let bvh = tracer::bvh::build(&scene.triangles).unwrap();
    if let Ok(px) = std::env::var("PIXEL") {
        let v: Vec<u32> = px.split(',').map(|s| s.parse().unwrap()).collect();
        for strategy in Strategy::ALL {
            let settings = RenderSettings { width: 64, height: 64, strategy, max_depth: depth };
            let mut r = CpuRenderer::new(pack(&scene, &bvh, &settings).unwrap(), 1);
            let mut sum = 0.0f64;
            let mut nz = 0;
            let n = 200000;
            for _ in 0..n {
                let s = r.sample_pixel(v[0], v[1]).x as f64;
                sum += s;
                if s > 0.0 {
                    nz += 1;
                }
                r.render_frame_count_only();
            }
            println!("{strategy:?} pixel mean {} nonzero {}", sum / n as f64, nz);
        }
        return;
    }
    let mut images = Vec::new();
    for strategy in Strategy::ALL {
        let settings = RenderSettings { width: 64, height: 64, strategy, max_depth: depth };
        let mut r = CpuRenderer::new(pack(&scene, &bvh, &settings).unwrap(), 1);
        for _ in 0..256 {
            r.render_frame();
        }
        let img = r.image();
        let top = img.pixels[..64 * 20].iter().copied().sum::<glam::Vec3>() / (64.0 * 20.0);
        let bottom = img.pixels[64 * 44..].iter().copied().sum::<glam::Vec3>() / (64.0 * 20.0);
        println!("{:?} mean {:?} top {:?} bottom {:?}", strategy, img.mean().x, top.x, bottom.x);
        images.push(img);
    }
    if std::env::var("DIFF").is_ok() {
        for y in 0..24 {
            let row: String = (0..64)
                .map(|x| {
                    let a = images[0].pixels[y * 64 + x].x;
                    let b = images[1].pixels[y * 64 + x].x;
                    let d = (a - b) / (a + b + 1e-3);
                    if d > 0.2 {
                        '#'
                    } else if d > 0.05 {
                        '+'
                    } else if d < -0.05 {
                        '-'
                    } else {
                        '.'
                    }
                })
                .collect();
            println!("{row}");
        }
    }
}
