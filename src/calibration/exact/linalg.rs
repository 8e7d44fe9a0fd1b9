//! Dense 3×3 linear algebra of the normal equations: Gaussian elimination with partial pivoting.

use crate::util::num::fmax;

pub(super) type Mat = [[f64; 3]; 3];

/// Solves `a x = b` for the leading `n × n` block (Gaussian elimination, partial pivoting).
/// `None` when the matrix is singular to working precision.
pub(crate) fn solve(mut a: Mat, mut b: [f64; 3], n: usize) -> Option<[f64; 3]> {
    let scale = (0..n).fold(0.0, |m, i| fmax(m, libm::fabs(a[i][i])));
    if !(scale > 0.0 && scale.is_finite()) {
        return None;
    }
    for c in 0..n {
        let mut piv = c;
        for r in c + 1..n {
            if libm::fabs(a[r][c]) > libm::fabs(a[piv][c]) {
                piv = r;
            }
        }
        if libm::fabs(a[piv][c]) <= 1e-14 * scale {
            return None;
        }
        // Element by element, not `a.swap(c, piv)` (nor whole-row assignments): those may
        // overlap (`c == piv`) and compile to `memmove`, 1.5 KiB of flash the firmware
        // otherwise does without.
        for k in 0..3 {
            let t = a[c][k];
            a[c][k] = a[piv][k];
            a[piv][k] = t;
        }
        b.swap(c, piv);
        for r in c + 1..n {
            let f = a[r][c] / a[c][c];
            for k in c..n {
                a[r][k] -= f * a[c][k];
            }
            b[r] -= f * b[c];
        }
    }
    let mut x = [0.0; 3];
    for c in (0..n).rev() {
        let mut s = b[c];
        for k in c + 1..n {
            s -= a[c][k] * x[k];
        }
        x[c] = s / a[c][c];
    }
    x.iter().all(|v| v.is_finite()).then_some(x)
}

#[cfg(test)]
mod tests {
    use super::*;
    #[test]
    fn solve_3x3_and_singular() {
        let a = [[4.0, 1.0, 2.0], [1.0, 3.0, 0.0], [2.0, 0.0, 5.0]];
        let x = solve(a, [7.0, 4.0, 7.0], 3).unwrap();
        // The system was built from x = (1, 1, 1).
        for v in x {
            assert!((v - 1.0).abs() < 1e-14);
        }
        let singular = [[1.0, 2.0, 0.0], [2.0, 4.0, 0.0], [0.0, 0.0, 0.0]];
        assert!(solve(singular, [1.0, 2.0, 0.0], 2).is_none());
    }
}
