//! Volume compositing along one ray (paper Eq. 2, DESIGN §2.2), forward and backward.
//!
//! Samples `i = 1..N` at distances `t_i` with step `δ_i` and density `σ_i`:
//! `α_i = 1 − e^{−σ_i δ_i}`, `T_i = Π_{j<i} (1 − α_j)`, `w_i = T_i α_i`,
//! `C = Σ w_i c_i + T_{N+1} c_bg`. Marching stops once `T < 1e-4`
//! ([`EARLY_STOP_TRANSMITTANCE`]): later samples get weight 0, and the background term uses
//! the transmittance at the stop — forward and backward agree on that truncated sample list.
//!
//! **Backward with O(1) memory per ray** (Instant-NGP's suffix trick). Since
//! `∂(T_i α_i)/∂σ_k = −δ_k T_i α_i` for `i > k`, `δ_k T_{k+1}` for `i = k`, and
//! `∂T_{N+1}/∂σ_k = −δ_k T_{N+1}`:
//! `∂C/∂σ_k = δ_k (T_{k+1} c_k − (C − Σ_{i≤k} w_i c_i))`, and `∂C/∂c_k = w_k`.
//! The backward walks the ray again with a running prefix sum, needing only the forward's `C`.
//!
//! Worked example (one ray, two samples, δ = 1): σ = (ln 2, ln 2) gives α = (½, ½),
//! T = (1, ½, ¼), w = (½, ¼); with c = (1, 0) per channel and c_bg = 0: C = ½, T_final = ¼.

/// Transmittance below which marching stops.
pub const EARLY_STOP_TRANSMITTANCE: f32 = 1e-4;

/// Whether a ray whose transmittance has fallen to `transmittance` is opaque: later samples
/// are ignored (the early stop of training, rendering and compositing).
#[inline]
pub fn is_opaque(transmittance: f32) -> bool {
    transmittance < EARLY_STOP_TRANSMITTANCE
}

/// The share of light a sample of density `sigma` and step `delta` lets through, `e^{−σδ}`.
#[inline]
pub fn transmitted(sigma: f32, delta: f32) -> f32 {
    (-sigma * delta).exp()
}

/// The forward result of one ray.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RayComposite {
    /// Composited colour `C`, background term included.
    pub rgb: [f32; 3],
    /// Opacity `Σ w_i` (= 1 − `transmittance`).
    pub opacity: f32,
    /// Expected range `Σ w_i t_i` (paper Eq. 3, not normalised by opacity).
    pub depth: f32,
    /// Transmittance left after the last sample used, `T_{N+1}`.
    pub transmittance: f32,
    /// Samples used before the early stop.
    pub samples_used: usize,
}

/// `weights[i] = w_i`; returns (transmittance after the last used sample, samples used).
/// Samples after the early stop get weight 0.
pub fn weights_from_density(sigma: &[f32], delta: &[f32], weights: &mut [f32]) -> (f32, usize) {
    assert!(sigma.len() == delta.len() && weights.len() == sigma.len(), "composite: sample arrays differ in length");
    let mut t = 1.0f32;
    let mut used = sigma.len();
    for i in 0..sigma.len() {
        if is_opaque(t) {
            used = i;
            weights[i..].fill(0.0);
            break;
        }
        let keep = transmitted(sigma[i], delta[i]);
        weights[i] = t * (1.0 - keep);
        t *= keep;
    }
    (t, used)
}

/// Composites one ray: densities `sigma`, steps `delta`, distances `t`, colours `rgb`
/// (activated, in `[0, 1]`) and the background colour `bg`.
pub fn composite_ray(sigma: &[f32], delta: &[f32], t: &[f32], rgb: &[[f32; 3]], bg: [f32; 3]) -> RayComposite {
    let n = sigma.len();
    assert!(delta.len() == n && t.len() == n && rgb.len() == n, "composite: sample arrays differ in length");
    let mut acc = RayAccumulator::new();
    for i in 0..n {
        if acc.is_opaque() {
            break;
        }
        acc.push(sigma[i], delta[i], t[i], rgb[i]);
    }
    acc.finish(bg)
}

/// [`composite_ray`] one sample at a time, for renderers that march a ray in segments and
/// stop early: pushing the same samples (while not [`RayAccumulator::is_opaque`]) gives the
/// same bits as `composite_ray`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RayAccumulator {
    acc: RayComposite,
}

impl Default for RayAccumulator {
    fn default() -> Self {
        RayAccumulator::new()
    }
}

impl RayAccumulator {
    /// An empty ray (transmittance 1).
    pub fn new() -> RayAccumulator {
        RayAccumulator {
            acc: RayComposite { rgb: [0.0; 3], opacity: 0.0, depth: 0.0, transmittance: 1.0, samples_used: 0 },
        }
    }

    /// Whether the transmittance fell below [`EARLY_STOP_TRANSMITTANCE`] (later samples would
    /// be ignored).
    #[inline]
    pub fn is_opaque(&self) -> bool {
        is_opaque(self.acc.transmittance)
    }

    /// The light still passing after the samples pushed so far.
    #[inline]
    pub fn transmittance(&self) -> f32 {
        self.acc.transmittance
    }

    /// Adds the next sample (activated density and colour); returns its weight `w = T·α`.
    #[inline]
    pub fn push(&mut self, sigma: f32, delta: f32, t: f32, rgb: [f32; 3]) -> f32 {
        self.push_kept(transmitted(sigma, delta), t, rgb)
    }

    /// [`RayAccumulator::push`] with the sample's transmitted share `keep = e^{−σδ}`
    /// ([`transmitted`]) already computed: the same bits.
    #[inline]
    pub fn push_kept(&mut self, keep: f32, t: f32, rgb: [f32; 3]) -> f32 {
        let a = &mut self.acc;
        let w = a.transmittance * (1.0 - keep);
        for c in 0..3 {
            a.rgb[c] += w * rgb[c];
        }
        a.opacity += w;
        a.depth += w * t;
        a.transmittance *= keep;
        a.samples_used += 1;
        w
    }

    /// The composite with the background term `T · bg` added.
    pub fn finish(&self, bg: [f32; 3]) -> RayComposite {
        let mut out = self.acc;
        for c in 0..3 {
            out.rgb[c] += out.transmittance * bg[c];
        }
        out
    }
}

/// Backward of [`composite_ray`] for a loss `L` with `d_rgb = ∂L/∂C`: writes `∂L/∂σ_i` to
/// `d_sigma` and `∂L/∂c_i` to `d_rgb_samples` (zero past the early stop). `fwd` is the
/// forward's result for the same inputs. O(1) extra memory.
pub fn composite_ray_backward(
    sigma: &[f32],
    delta: &[f32],
    rgb: &[[f32; 3]],
    fwd: &RayComposite,
    d_rgb: [f32; 3],
    d_sigma: &mut [f32],
    d_rgb_samples: &mut [[f32; 3]],
) {
    let n = sigma.len();
    assert!(
        delta.len() == n && rgb.len() == n && d_sigma.len() == n && d_rgb_samples.len() == n,
        "composite: sample arrays differ in length"
    );
    let used = fwd.samples_used.min(n);
    let mut trans = 1.0f32;
    let mut prefix = [0f32; 3];
    for i in 0..used {
        let keep = transmitted(sigma[i], delta[i]);
        let w = trans * (1.0 - keep);
        let t_next = trans * keep;
        let mut g = 0.0;
        for c in 0..3 {
            prefix[c] += w * rgb[i][c];
            let suffix = fwd.rgb[c] - prefix[c];
            g += d_rgb[c] * (t_next * rgb[i][c] - suffix);
            d_rgb_samples[i][c] = w * d_rgb[c];
        }
        d_sigma[i] = delta[i] * g;
        trans = t_next;
    }
    d_sigma[used..].fill(0.0);
    d_rgb_samples[used..].fill([0.0; 3]);
}
