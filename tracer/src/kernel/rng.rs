#[kernel_dsl::kernel]
pub mod rng {
    //! Random numbers exactly as LightHouse: a per-pixel seed from Thomas Wang's integer hash,
    //! then an xorshift32 stream; and the film position of each frame's sample in its pixel.

    use glam::Vec2;

    /// Thomas Wang's 32-bit integer hash.
    pub fn wang_hash(seed: u32) -> u32 {
        let mut s = (seed ^ 61) ^ (seed >> 16);
        s = s.wrapping_mul(9);
        s ^= s >> 4;
        s = s.wrapping_mul(0x27d4eb2d);
        s ^= s >> 15;
        s
    }

    /// Marsaglia's xorshift32: advances the state and returns it.
    pub fn random_u32(state: &mut u32) -> u32 {
        *state ^= *state << 13;
        *state ^= *state >> 17;
        *state ^= *state << 5;
        *state
    }

    /// A uniform float in [0, 1). Uses the top 24 bits, so every value is exact in f32 and the
    /// result is at most 1 - 2^-24: `x as f32 * 2^-32` would round up to 1.0 for large `x`.
    pub fn random_float(state: &mut u32) -> f32 {
        (random_u32(state) >> 8) as f32 * (1.0 / 16777216.0)
    }

    /// R2's multipliers (Roberts 2018: 1/g and 1/g² for the plastic number g) in 0.32 fixed point.
    pub const R2_X: u32 = 3242174889;
    pub const R2_Y: u32 = 2447445413;
    /// What `frame_seed` mixes the frame index with (`tracer::backend::frame_seed`): xor-ing
    /// `frame * FRAME_MIX` out of it leaves the part that is the same for every frame of a render.
    pub const FRAME_MIX: u32 = 0x9e3779b9;

    /// The seed of frame `frame` of a render with seed `seed`: spreads consecutive frames over
    /// the hash's input space. `pixel_jitter` xors `frame * FRAME_MIX` back out for the part of
    /// the seed common to a render's frames. (Hosts set it per frame for the megakernel; the
    /// wavefront's `generate` stage computes it for the frame it fills.)
    pub fn seed_of_frame(frame: u32, seed: u32) -> u32 {
        frame.wrapping_mul(FRAME_MIX) ^ seed.wrapping_mul(0x85eb_ca6b)
    }

    /// Where in pixel `pixel_index` the sample of frame `frame_index` lies, in [0, 1)²: R2, a
    /// rank-1 lattice over the frames, shifted per pixel by a random offset that stays the same
    /// from frame to frame (a Cranley–Patterson rotation, from the render's seed). A pixel's
    /// successive samples then spread evenly over it (16 samples cover it as a 4x4 grid would,
    /// so edges and texture detail converge faster than with independent jitter), and
    /// neighbouring pixels' patterns are unrelated.
    pub fn pixel_jitter(pixel_index: u32, frame_seed: u32, frame_index: u32) -> Vec2 {
        let render_seed = frame_seed ^ frame_index.wrapping_mul(FRAME_MIX);
        let mut state = pixel_seed(pixel_index, render_seed ^ 0x5bd1e995);
        let x = random_u32(&mut state).wrapping_add(frame_index.wrapping_mul(R2_X));
        let y = random_u32(&mut state).wrapping_add(frame_index.wrapping_mul(R2_Y));
        Vec2::new((x >> 8) as f32 * (1.0 / 16777216.0), (y >> 8) as f32 * (1.0 / 16777216.0))
    }

    /// The stream's first state for a pixel and frame. xorshift32 never leaves zero, so a
    /// zero hash is replaced.
    pub fn pixel_seed(pixel_index: u32, frame_seed: u32) -> u32 {
        let s = wang_hash(pixel_index.wrapping_add(frame_seed));
        if s == 0 {
            0x9e3779b9
        } else {
            s
        }
    }
}
