//! An MLP's parameters: the flat fp32 weights, their per-layer transposes (for dL/dx) and, for
//! the AMX level, both rounded to bf16 and packed the way the tiles read them ([`pack_vnni`]).

use super::*;

/// Rounds to bf16 (nearest even; NaN stays NaN), as `vcvtne2ps2bf16` does.
pub fn bf16_bits(v: f32) -> u16 {
    let b = v.to_bits();
    if v.is_nan() {
        return ((b >> 16) | 0x40) as u16;
    }
    (b.wrapping_add(0x7fff + ((b >> 16) & 1)) >> 16) as u16
}

/// Packs the `k × o` row-major matrix `w` for the tiles: bf16, `k` padded with zero rows to a
/// multiple of 32, pairs of consecutive rows interleaved (`packed[(kk/2)·2o + 2j + kk%2] =
/// w[kk][j]`), the layout `tdpbf16ps` reads its second operand in. Length `k.next_multiple_of(32) · o`.
pub fn pack_vnni(w: &[f32], k: usize, o: usize, packed: &mut [u16]) {
    let k32 = k.next_multiple_of(32);
    assert!(w.len() >= k * o && packed.len() >= k32 * o, "pack_vnni: buffers too short");
    packed[..k32 * o].fill(0);
    for kk in 0..k {
        for j in 0..o {
            packed[(kk / 2) * 2 * o + 2 * j + kk % 2] = bf16_bits(w[kk * o + j]);
        }
    }
}

/// An MLP's weights (flat, layer views as in [`Mlp::layers`]) and their per-layer transposes,
/// which backward needs for dL/dx = dz·Wᵀ. Like the hash grid's fp16 mirror, the transposed
/// copy is rewritten once per optimiser step ([`MlpParams::sync`]), not once per batch;
/// [`MlpParams::weights_mut`] marks it stale and backward refuses stale weights.
#[derive(Clone, Debug, PartialEq)]
pub struct MlpParams {
    pub(super) weights: Vec<f32>,
    pub(super) transposed: Vec<f32>,
    /// Per layer, `W` and `Wᵀ` rounded to bf16 and packed for the AMX level ([`pack_vnni`]),
    /// at `packed_at[l]`: rewritten with the transposed copy.
    pub(super) packed: Vec<u16>,
    pub(super) packed_t: Vec<u16>,
    pub(super) packed_at: Vec<(usize, usize)>,
    pub(super) layers: Vec<LayerShape>,
    pub(super) synced: bool,
}

impl MlpParams {
    /// Wraps `weights` (length [`Mlp::n_params`]) for `mlp`.
    pub fn new<const W: usize>(mlp: &Mlp<W>, weights: Vec<f32>) -> MlpParams {
        assert_eq!(weights.len(), mlp.n_params(), "mlp: parameter buffer has the wrong length");
        let (mut at, mut at_t) = (0, 0);
        let packed_at: Vec<(usize, usize)> = mlp
            .layers
            .iter()
            .map(|l| {
                let here = (at, at_t);
                at += l.k.next_multiple_of(32) * l.o;
                at_t += l.o.next_multiple_of(32) * l.k;
                here
            })
            .collect();
        let mut p = MlpParams {
            transposed: vec![0.0; weights.len()],
            weights,
            packed: vec![0; at],
            packed_t: vec![0; at_t],
            packed_at,
            layers: mlp.layers.clone(),
            synced: false,
        };
        p.sync();
        p
    }

    /// Layer `l`'s weights for the kernels.
    pub(super) fn layer(&self, l: usize) -> LayerWeights<'_> {
        let s = self.layers[l];
        let at = self.packed_at[l].0;
        LayerWeights {
            f32: &self.weights[s.offset..s.offset + s.k * s.o],
            bf16: &self.packed[at..at + s.k.next_multiple_of(32) * s.o],
        }
    }

    /// Layer `l`'s `Wᵀ` (`o × k`) for the kernels.
    pub(super) fn layer_transposed(&self, l: usize) -> LayerWeights<'_> {
        let s = self.layers[l];
        let at = self.packed_at[l].1;
        LayerWeights {
            f32: &self.transposed[s.offset..s.offset + s.k * s.o],
            bf16: &self.packed_t[at..at + s.o.next_multiple_of(32) * s.k],
        }
    }

    /// The weights.
    pub fn weights(&self) -> &[f32] {
        &self.weights
    }

    /// Mutable weights (for the optimiser); call [`MlpParams::sync`] before the next backward.
    pub fn weights_mut(&mut self) -> &mut [f32] {
        self.synced = false;
        &mut self.weights
    }

    /// Rewrites the transposed copy and the bf16 packs from the weights.
    pub fn sync(&mut self) {
        for (l, &(at, at_t)) in self.layers.iter().zip(&self.packed_at) {
            for kk in 0..l.k {
                for j in 0..l.o {
                    self.transposed[l.offset + j * l.k + kk] = self.weights[l.offset + kk * l.o + j];
                }
            }
            let w = &self.weights[l.offset..l.offset + l.k * l.o];
            pack_vnni(w, l.k, l.o, &mut self.packed[at..]);
            let wt = &self.transposed[l.offset..l.offset + l.k * l.o];
            pack_vnni(wt, l.o, l.k, &mut self.packed_t[at_t..]);
        }
        self.synced = true;
    }
}
