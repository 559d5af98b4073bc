//! Residual-NeRF's per-sample mix (paper Eqs. 5–6): β = 0 gives the background exactly, β = 1
//! the residual exactly (both density variants); the sum variant is Eq. 6; gradients into the
//! residual and the Mixnet match f64 finite differences of an independent f64 implementation.

mod common;

use proptest::prelude::*;
use residual_nerf::field::mix::{mix_backward, mix_forward, DensityMix, MixInput, MixKind};

fn sig(x: f32) -> f32 {
    1.0 / (1.0 + (-x).exp())
}

fn input() -> impl Strategy<Value = MixInput> {
    (-4f32..4.0, prop::array::uniform3(-4f32..4.0), -4f32..4.0, prop::array::uniform3(-4f32..4.0), -5f32..5.0)
        .prop_map(|(s_bg, c_bg, s_res, c_res, m)| MixInput { s_bg, c_bg, s_res, c_res, m })
}

const VARIANTS: [DensityMix; 2] = [DensityMix::Activated, DensityMix::Raw];

/// f64 reference of DESIGN §2.3: (σ, c).
fn mix_f64(kind: MixKind, x: [f64; 9]) -> (f64, [f64; 3]) {
    let [s_bg, cb0, cb1, cb2, s_res, cr0, cr1, cr2, m] = x;
    let s = |v: f64| 1.0 / (1.0 + (-v).exp());
    let (cb, cr) = ([cb0, cb1, cb2], [cr0, cr1, cr2]);
    match kind {
        MixKind::Sum => (s_bg.exp() + s_res.exp(), std::array::from_fn(|k| s(cb[k] + cr[k]))),
        MixKind::Mixnet(d) => {
            let b = s(m);
            let sigma = match d {
                DensityMix::Activated => (1.0 - b) * s_bg.exp() + b * s_res.exp(),
                DensityMix::Raw => ((1.0 - b) * s_bg + b * s_res).exp(),
            };
            (sigma, std::array::from_fn(|k| s((1.0 - b) * cb[k] + b * cr[k])))
        }
    }
}

proptest! {
    #![proptest_config(common::cases(64))]

    #[test]
    fn beta_zero_is_the_background_and_beta_one_the_residual(x in input()) {
        for d in VARIANTS {
            let kind = MixKind::Mixnet(d);
            let bg = mix_forward(kind, &MixInput { m: -200.0, ..x });
            prop_assert_eq!(bg.beta, 0.0);
            prop_assert_eq!(bg.sigma, x.s_bg.exp());
            prop_assert_eq!(bg.rgb, x.c_bg.map(sig));
            let res = mix_forward(kind, &MixInput { m: 200.0, ..x });
            prop_assert_eq!(res.beta, 1.0);
            prop_assert_eq!(res.sigma, x.s_res.exp());
            prop_assert_eq!(res.rgb, x.c_res.map(sig));
        }
    }

    #[test]
    fn sum_variant_is_equation_six(x in input()) {
        let o = mix_forward(MixKind::Sum, &x);
        prop_assert_eq!(o.sigma, x.s_bg.exp() + x.s_res.exp());
        for k in 0..3 {
            prop_assert_eq!(o.rgb[k], sig(x.c_bg[k] + x.c_res[k]));
        }
    }

    #[test]
    fn gradients_match_f64_finite_differences(
        x in input(),
        a in -2f64..2.0,
        b in prop::array::uniform3(-2f64..2.0),
    ) {
        for kind in [MixKind::Mixnet(DensityMix::Activated), MixKind::Mixnet(DensityMix::Raw), MixKind::Sum] {
            // L = a·σ + Σ b_k c_k.
            let loss = |v: [f64; 9]| {
                let (s, c) = mix_f64(kind, v);
                a * s + (0..3).map(|k| b[k] * c[k]).sum::<f64>()
            };
            let out = mix_forward(kind, &x);
            let g = mix_backward(kind, &x, &out, a as f32, b.map(|v| v as f32));
            let v0 = [x.s_bg, x.c_bg[0], x.c_bg[1], x.c_bg[2], x.s_res, x.c_res[0], x.c_res[1], x.c_res[2], x.m].map(|v| v as f64);
            let fd = |i: usize| {
                let h = 1e-6;
                let (mut p, mut q) = (v0, v0);
                p[i] += h;
                q[i] -= h;
                (loss(p) - loss(q)) / (2.0 * h)
            };
            let got = [(4, g.s_res), (5, g.c_res[0]), (6, g.c_res[1]), (7, g.c_res[2]), (8, g.m)];
            let scale = 1.0 + loss(v0).abs() + mix_f64(kind, v0).0;
            for (i, gi) in got {
                let want = fd(i);
                prop_assert!((gi as f64 - want).abs() <= 2e-4 * scale, "{kind:?} input {i}: {gi} vs {want}");
            }
        }
    }
}
