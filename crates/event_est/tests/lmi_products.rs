//! The LMI builder's product terms evaluate to the dense products they stand for: M·U·G for a
//! full variable U (`add_full_product`, `add_full_times`), M·S for a symmetric S
//! (`add_times_sym`), and single entries (`add_entry`).
#![allow(clippy::unwrap_used)]

use event_est::lmi::{Problem, Vars};
use nalgebra::DMatrix;
use proptest::prelude::*;

proptest! {
    #[test]
    fn product_terms_match_dense_products(
        v in proptest::collection::vec(-2.0f64..2.0, 64), c0 in 0usize..2,
    ) {
        let (h, n, p, k) = (2, 3, 2, 2);
        let m = DMatrix::from_column_slice(h, n, &v[0..6]);
        let g = DMatrix::from_column_slice(p, k, &v[6..10]);
        let mt = DMatrix::from_column_slice(h, n, &v[10..16]);
        let mut vars = Vars::default();
        let u = vars.full(n, p);
        let s = vars.sym(n);
        let x: Vec<f64> = v[16..16 + vars.len()].to_vec();
        let mut prob = Problem::new(vars);
        // Off-diagonal block at (0, col), col ≥ h (upper triangle), shifted by c0.
        let col = h + 2 + c0;
        let dim = col + k.max(n);
        {
            let lm = prob.lmi("products", dim);
            lm.add_full_product(Some(&m), u, &g, 0..p, (0, col), 1.5);
            lm.add_times_sym(&mt, s, 0, col, -0.5);
            lm.add_entry(u.index(1, 1), 0, 1, 2.0);
        }
        let got = prob.lmis[0].evaluate(&x);
        let uv = u.value(&x);
        let sv = s.value(&x);
        let mut want = DMatrix::zeros(dim, dim);
        want.view_mut((0, col), (h, k)).copy_from(&(&m * &uv * &g * 1.5));
        let ms = &mt * &sv * -0.5;
        for i in 0..h {
            for j in 0..n {
                want[(i, col + j)] += ms[(i, j)];
            }
        }
        want[(0, 1)] += 2.0 * uv[(1, 1)];
        let want = &want + want.transpose();
        prop_assert!((got - want).amax() < 1e-12);
    }

    /// Without a left factor the product is U[:, cols]·G[cols, :] (only the chosen columns).
    #[test]
    fn full_times_uses_only_the_chosen_columns(v in proptest::collection::vec(-2.0f64..2.0, 24)) {
        let mut vars = Vars::default();
        let u = vars.full(2, 3);
        let x: Vec<f64> = v[..6].to_vec();
        let g = DMatrix::from_column_slice(3, 2, &v[6..12]);
        let mut prob = Problem::new(vars);
        prob.lmi("U G", 4).add_full_times(u, &g, 1..3, 0, 2, 1.0);
        let got = prob.lmis[0].evaluate(&x);
        let uv = u.value(&x);
        let block = uv.columns(1, 2) * g.rows(1, 2);
        prop_assert!((got.view((0, 2), (2, 2)) - &block).amax() < 1e-12);
        prop_assert!((got.view((2, 0), (2, 2)) - block.transpose()).amax() < 1e-12);
    }
}
