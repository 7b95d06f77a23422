//! Frames split into bands of rows, shared by the CPU (`tests/rendering/cpu.rs`), GL (`tests/cli/web.rs`, the
//! page's loop) and wgpu (`tests/rendering/wgpu.rs`) tests, through the `Renderer` trait: whatever the
//! split, a frame is the frame rendered whole, exactly.

use tracer::backend::Renderer;

/// Asserts that `a` and `b` hold the same accumulation, bit for bit, and that it is a real
/// image (not black, every pixel carrying every sample of the frames rendered).
pub fn assert_same(a: &dyn Renderer, b: &dyn Renderer, what: &str) {
    let (x, y) = (a.accumulation().expect("readback"), b.accumulation().expect("readback"));
    let differing = x.iter().zip(&y).filter(|(p, q)| p != q).count();
    assert_eq!(differing, 0, "{what}: {differing} of {} pixels differ", x.len());
    assert!(x.iter().all(|p| p.w == a.frames() as f32), "{what}: every pixel has every sample");
    assert!(x.iter().map(|p| p.x as f64).sum::<f64>() > 0.0, "{what}: black");
}

/// Renders four frames whole on `whole` and in bands of uneven heights (changing within and
/// across frames; not multiples of any workgroup height, so a band's last workgroup reaches
/// into the next band's rows) on `banded`, both of `height` rows from the same packed scene
/// and seed; the sample count advances with a frame's last band only, and a restart in the
/// middle of a split frame leaves nothing of it behind.
pub fn assert_bands_make_the_whole_frame(whole: &mut dyn Renderer, banded: &mut dyn Renderer, height: u32) {
    assert!(height > 13, "the band heights need a taller image than {height} rows");
    let mut heights = [5u32, 7, 1, 13, height, 3, 11].into_iter().cycle();
    let mut bands = 0;
    for frame in 0..4 {
        whole.render_frame().expect("frame");
        bands += 1;
        while !banded.render_band(heights.next().unwrap()).expect("band") {
            assert_eq!(banded.frames(), frame, "the sample count advances with the frame's last band only");
            bands += 1;
        }
        assert_eq!(banded.frames(), frame + 1);
        assert_same(whole, banded, &format!("frame {frame}"));
    }
    assert!(bands >= 12, "frames were split: {bands} bands");
    banded.render_band(6).expect("band");
    assert_eq!(banded.rows_left(), height - 6);
    banded.restart().expect("restart");
    whole.restart().expect("restart");
    assert_eq!(banded.rows_left(), height, "a restart abandons the split frame");
    for _ in 0..2 {
        whole.render_frame().expect("frame");
        while !banded.render_band(height / 2 - 1).expect("band") {}
    }
    assert_same(whole, banded, "after a restart in the middle of a frame");
}
