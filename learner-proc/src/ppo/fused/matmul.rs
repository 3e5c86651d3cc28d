//! Matrix products over host slices, through the `gemm` crate (the kernels burn's `flex`
//! backend calls too): packed, SIMD micro-kernels chosen at run time for the CPU, one thread.
//!
//! A [`Mat`] is a strided view of a slice, so a transpose is a view with its strides swapped
//! and no copy: the backward pass's `Hᵀ·dZ` and `dZ·Wᵀ` read the forward's buffers in place.

/// A `rows × cols` matrix view of a slice: element `(i, j)` at `i·row_stride + j·col_stride`.
#[derive(Clone, Copy)]
pub struct Mat<'a> {
    data: &'a [f32],
    rows: usize,
    cols: usize,
    row_stride: usize,
    col_stride: usize,
}

impl<'a> Mat<'a> {
    /// The first `rows × cols` values of `data`, row-major.
    pub fn new(data: &'a [f32], rows: usize, cols: usize) -> Self {
        assert!(
            data.len() >= rows * cols,
            "{rows}×{cols} view of {} values",
            data.len()
        );
        Self {
            data,
            rows,
            cols,
            row_stride: cols,
            col_stride: 1,
        }
    }

    /// The transpose, sharing the data.
    pub fn t(self) -> Self {
        Self {
            data: self.data,
            rows: self.cols,
            cols: self.rows,
            row_stride: self.col_stride,
            col_stride: self.row_stride,
        }
    }
}

/// `dst = dst·keep + lhs·rhs`, with `dst` a row-major `lhs.rows × rhs.cols` block at the start
/// of `dst`; `keep` false overwrites (`dst` is then not read, so it may hold anything).
pub fn matmul(dst: &mut [f32], lhs: Mat, rhs: Mat, keep: bool) {
    let (m, k, n) = (lhs.rows, lhs.cols, rhs.cols);
    assert_eq!(k, rhs.rows, "inner dimensions {k} and {}", rhs.rows);
    assert!(
        dst.len() >= m * n,
        "{m}×{n} product into {} values",
        dst.len()
    );
    if m == 0 || n == 0 {
        return;
    }
    let stride = |s: usize| isize::try_from(s).expect("stride fits isize");
    // SAFETY: each view's `new` checked that its slice holds every element its shape and
    // strides address (a transpose addresses the same elements), `dst` holds `m × n` values
    // row-major, and `dst` is a unique borrow, so it overlaps neither operand. `gemm` reads
    // `dst` only when `read_dst` is true, and with `Parallelism::None` runs on this thread.
    unsafe {
        gemm::gemm(
            m,
            n,
            k,
            dst.as_mut_ptr(),
            1,
            stride(n),
            keep,
            lhs.data.as_ptr(),
            stride(lhs.col_stride),
            stride(lhs.row_stride),
            rhs.data.as_ptr(),
            stride(rhs.col_stride),
            stride(rhs.row_stride),
            1.0f32,
            1.0f32,
            false,
            false,
            false,
            gemm::Parallelism::None,
        );
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// [[1, 2, 3], [4, 5, 6]] · [[1, 0], [0, 1], [1, 1]] = [[4, 5], [10, 11]], by hand; with
    /// `keep` it adds to what `dst` held; and transposed views read the same buffers.
    #[test]
    fn products_and_transposes_by_hand() {
        let a = [1.0, 2.0, 3.0, 4.0, 5.0, 6.0];
        let b = [1.0, 0.0, 0.0, 1.0, 1.0, 1.0];
        let mut c = [f32::NAN; 4];
        matmul(&mut c, Mat::new(&a, 2, 3), Mat::new(&b, 3, 2), false);
        assert_eq!(c, [4.0, 5.0, 10.0, 11.0]);
        matmul(&mut c, Mat::new(&a, 2, 3), Mat::new(&b, 3, 2), true);
        assert_eq!(c, [8.0, 10.0, 20.0, 22.0]);
        // aᵀ · a = [[17, 22, 27], [22, 29, 36], [27, 36, 45]].
        let mut g = [0.0; 9];
        matmul(&mut g, Mat::new(&a, 2, 3).t(), Mat::new(&a, 2, 3), false);
        assert_eq!(g, [17.0, 22.0, 27.0, 22.0, 29.0, 36.0, 27.0, 36.0, 45.0]);
        // a · aᵀ = [[14, 32], [32, 77]].
        let mut h = [0.0; 4];
        matmul(&mut h, Mat::new(&a, 2, 3), Mat::new(&a, 2, 3).t(), false);
        assert_eq!(h, [14.0, 32.0, 32.0, 77.0]);
    }

    #[test]
    #[should_panic(expected = "inner dimensions")]
    fn mismatched_shapes_are_refused() {
        let a = [0.0; 6];
        matmul(&mut [0.0; 4], Mat::new(&a, 2, 3), Mat::new(&a, 2, 3), false);
    }
}
