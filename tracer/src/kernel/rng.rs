#[kernel_dsl::kernel]
pub mod rng {
    //! Random numbers exactly as LightHouse: a per-pixel seed from Thomas Wang's integer hash,
    //! then an xorshift32 stream.

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
