//! Elementwise loops compiled for the widest vector instructions the CPU has.
//!
//! The workspace builds for baseline x86-64 (SSE2), where the update's elementwise passes (the
//! tanh, Adam, gradient sums) run four floats at a time. [`vectorized`] runs a closure inlined
//! into a copy compiled for AVX-512 or AVX2, picked at run time (`pulp`, which gemm uses for its
//! kernels). Rust never fuses a multiply and an add on its own, so every copy performs the same
//! IEEE operations in the same order and gives the same bits.

/// Runs `f` compiled for this CPU's widest vector instructions.
#[inline(always)]
pub fn vectorized<R>(f: impl FnOnce() -> R) -> R {
    pulp::Arch::new().dispatch(f)
}

/// Σ x², accumulated in f64 over eight interleaved lanes (element `i` to lane `i mod 8`)
/// that are then added in lane order: a fixed order, as a plain running sum, but one whose
/// eight additions are independent and so vectorise.
pub fn sum_of_squares(xs: &[f32]) -> f64 {
    vectorized(|| {
        let mut lanes = [0.0f64; 8];
        let chunks = xs.chunks_exact(8);
        let rest = chunks.remainder();
        for chunk in chunks {
            for (lane, &x) in lanes.iter_mut().zip(chunk) {
                *lane += f64::from(x) * f64::from(x);
            }
        }
        for (lane, &x) in lanes.iter_mut().zip(rest) {
            *lane += f64::from(x) * f64::from(x);
        }
        lanes.iter().sum()
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// 1² + … + 20² = 20·21·41/6 = 2870, across two full chunks of eight and a remainder.
    #[test]
    fn sum_of_squares_by_hand() {
        let xs: Vec<f32> = (1..=20).map(|i| i as f32).collect();
        assert_eq!(sum_of_squares(&xs), 2870.0);
        assert_eq!(sum_of_squares(&[]), 0.0);
        assert_eq!(sum_of_squares(&[3.0]), 9.0);
    }
}
