//! The BMC rule that turns one record's rays into irradiance, its posterior
//! variance and its rotation and translation gradients.
//!
//! Built once per (sample set, kernel, prior mean) and shared by every record:
//! the weights `w`, the Cholesky factor of `Q`, the kernel-mean derivatives
//! `dz_i/dμ_i` and the kernel derivatives `∂k/∂(ω_i·ω_j)` depend only on the
//! local-frame directions, never on the observed radiance (docs/math.md §3).
//!
//! # Gradients: derivatives of the GP posterior mean
//! We differentiate the BMC estimate itself instead of using Ward & Heckbert
//! (1992) / Křivánek et al. (2005) gradients, which assume stratified
//! samples. Move the samples by a tangent field `ω_i → normalize(ω_i + ε δ_i)`
//! (relative to the density `p = cos θ/π`) while keeping the values `Y_i`.
//! With `α̃ = Q⁻¹(Y − m̂1)` (`m̂ = 0` for the zero prior mean, the GLS mean
//! otherwise) the first-order change of `Î = Σ w_i Y_i` is
//!
//! `dÎ/dε = Σ_i (dz_i/dμ_i) δ_i·ẑ α̃_i − Σ_{i≠j} w_i α̃_j ∂k/∂c (ω_i·ω_j) (δ_i·ω_j + ω_i·δ_j)`
//!
//! (derivative of `zᵀQ⁻¹Y`: `dzᵀQ⁻¹Y − zᵀQ⁻¹ dQ Q⁻¹Y`, Rasmussen & Williams
//! 2006 §A.3.1 for `d(Q⁻¹)`; for the GLS mean the `dm̂` terms combine into the
//! same form with the full weights `w` and `α̃`; `z_i` depends on `ω_i` only
//! through `μ_i = cos θ_i` for the Lambert density, docs/math.md §4).
//! - **Rotation** of the normal by `ε` about the local axis `a ∈ {x, y}`
//!   equals rotating the samples by `−ε` relative to the density:
//!   `δ_i = −a × ω_i`. The rotation is rigid, so `dQ = 0` and only the
//!   kernel-mean term remains (Brouillat et al. 2009 keep `Q` fixed likewise).
//! - **Translation** by `ε` along the tangent `e ∈ {x, y}`: each ray saw a
//!   surface point `y_i = x + r_i ω_i`; from `x + ε e` it lies in direction
//!   `normalize(r_i ω_i − ε e)`, so `δ_i = −(e − (e·ω_i) ω_i)/r_i` (`0` for
//!   rays that escaped). Values are kept: the visible surfaces are taken as
//!   diffuse, the same assumption as Ward & Heckbert's translational
//!   gradient.
//! - **Occlusion.** With every sample at its own speed `s_i = 1/r_i`, the
//!   interpolant's step between a near occluder's samples and the far
//!   surface behind it moves at an average of their speeds, but the true
//!   edge moves with the occluder. Ward & Heckbert move each wall between
//!   neighbouring cells with the nearer hit of the two; likewise each
//!   sample here moves with the largest `1/r` among itself and its six
//!   nearest directions (`RecordRule::boundary_speeds`). Away from edges
//!   the neighbours' hits lie at about the same distance, so the speeds
//!   barely change. On the Cornell box this lowered the cached image's error
//!   against the converged reference from 2.57 % to 2.43 % (docs/BENCHMARKS.md).
//!
//! # Negative weights
//! Lambert rules on spherical Fibonacci sets (the default) have no negative
//! weights, but rules on stratified or random sets may. Where negatively
//! weighted rays meet a value far above the others and the BMC sum comes
//! out negative in a channel, the negative-weight guard of docs/math.md
//! §3.6 gives the record the equal-weight rule on the same rays instead,
//! with its sample variance and no gradients (they differentiate the
//! rejected GP mean).
//!
//! Unit tests check both gradients for the samples' own speeds against
//! finite differences of recomputed BMC estimates, the rotation gradient
//! against the closed form for a linear radiance field, and the occlusion
//! speeds against the analytic gradient at an occluding edge.

use crate::bmc::dense::dot;
use std::f64::consts::PI;

use glam::DVec3;

use super::error::CacheError;
use crate::bmc::dense::symmetric_product;
use crate::bmc::estimator::{SamplingPdf, importance_rule};
use crate::bmc::gls::Gls;
use crate::bmc::{
    Density, Factorisation, Kernel, KernelKind, KernelMeanMethod, PriorMean, Quadrature,
    kernel_means,
};
use crate::render::{RadianceSample, RenderError, Rgb};
use crate::sphere::{SampleSet, SampleSetSpec};

/// What a [`RecordRule`] is built from.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct RecordRuleSpec {
    /// Local-frame directions of every record's rays.
    pub samples: SampleSetSpec,
    /// GP prior over the incident radiance (its `σ²` cancels out of the
    /// records' variances, see [`RecordRule::estimate`]).
    pub kernel: Kernel,
    pub prior_mean: PriorMean,
}

/// BMC irradiance of one record with its variance and gradients, in the
/// record's local frame (z = normal). Units: W/m², gradients W/m² per radian
/// (rotation) and per world unit (translation).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RecordEstimate {
    /// `E = π Σ w_i L_i` (the Lambert rule integrates `L cos θ/π`, docs/math.md §1),
    /// or, where that sum is negative in a channel (module docs), `π` times
    /// the equal-weight rule on the same rays.
    pub irradiance: Rgb,
    /// Variance of `E` per channel: the posterior variance `π² V σ̂²`, with
    /// `V` the posterior variance of the rule and `σ̂² = ỸᵀQ₁⁻¹Ỹ/N` the
    /// maximum likelihood amplitude of the channel (docs/math.md §12.1) —
    /// the integration error of the rule — plus the Monte Carlo noise of the
    /// values, `π² Σ w_i² Var(L_i)` from the samples' own variances (zero
    /// when each value is a single path, whose spread is unknown). For the
    /// equal-weight fallback: `π²` times the sample variance of its terms
    /// over `N` (docs/math.md §3.6).
    pub variance: Rgb,
    /// `∂E/∂ε` for rotations of the normal about the local x and y axes
    /// (zero for the equal-weight fallback).
    pub rotation: [Rgb; 2],
    /// `∂E/∂ε` for translations along the local x and y axes.
    pub translation: [Rgb; 2],
}

/// Precomputed BMC rule for records (module docs).
#[derive(Clone, Debug)]
pub struct RecordRule {
    spec: RecordRuleSpec,
    set: SampleSet,
    factorisation: Factorisation,
    quadrature: Quadrature,
    /// `Q⁻¹1` and `1ᵀQ⁻¹1`, for the GLS mean `m̂ = (1ᵀQ⁻¹Y)/(1ᵀQ⁻¹1)`.
    gls: Gls,
    /// `dz_i/dμ_i`, `μ_i = cos θ_i`.
    dz_dmu: Vec<f64>,
    /// `A_ij = ∂k/∂c` at `c = ω_i·ω_j`, row-major `N×N`, zero on the
    /// diagonal (symmetric).
    dk_dc: Vec<f64>,
    /// `B_ij = A_ij (ω_i·ω_j)` (symmetric).
    dk_dc_cos: Vec<f64>,
    /// `A (w ∘ u_e)` for `u_e,i = e·ω_i`, `e` = local x and y.
    a_w_u: [Vec<f64>; 2],
    /// `B w`.
    b_w: Vec<f64>,
    /// The [`NEIGHBOURS`] directions nearest to each direction.
    neighbours: Vec<[usize; NEIGHBOURS]>,
}

impl RecordRule {
    /// Bytes held: the Cholesky factor and the derivative tables, `≈ 24 N²`
    /// for `N` directions (what a cache of records must count beside them).
    pub fn size_bytes(&self) -> usize {
        let f64s = self.dz_dmu.len()
            + self.dk_dc.len()
            + self.dk_dc_cos.len()
            + self.a_w_u.iter().map(Vec::len).sum::<usize>()
            + self.b_w.len();
        std::mem::size_of::<Self>()
            + self.factorisation.size_bytes()
            + self.quadrature.size_bytes()
            + self.set.directions.len() * std::mem::size_of::<glam::DVec3>()
            + f64s * std::mem::size_of::<f64>()
            + self.neighbours.len() * std::mem::size_of::<[usize; NEIGHBOURS]>()
            + self.gls.size_bytes()
    }

    /// Factor `Q`, compute the weights and the derivative tables.
    pub fn new(spec: RecordRuleSpec) -> Result<RecordRule, CacheError> {
        let set = SampleSet::generate(spec.samples)?;
        let factorisation = Factorisation::new(&set, &spec.kernel)?;
        let quadrature = Quadrature::new(
            &set,
            &spec.kernel,
            &factorisation,
            &Density::Lambert,
            spec.prior_mean,
            KernelMeanMethod::Exact,
        )?;
        let n = set.len();
        let gls = Gls::new(&factorisation);
        let dz_dmu = kernel_mean_slopes(&set.directions, &spec.kernel)?;
        let dirs = &set.directions;
        let (mut dk_dc, mut dk_dc_cos) = (vec![0.0; n * n], vec![0.0; n * n]);
        for i in 0..n {
            for j in 0..n {
                if i != j {
                    let a = kernel_slope(&spec.kernel, (dirs[i] - dirs[j]).length());
                    dk_dc[i * n + j] = a;
                    dk_dc_cos[i * n + j] = a * dirs[i].dot(dirs[j]);
                }
            }
        }
        let w = &quadrature.weights;
        let a_w_u = [0, 1].map(|e| {
            let v: Vec<f64> = dirs.iter().zip(w).map(|(d, w)| w * d[e]).collect();
            symmetric_product(&dk_dc, n, &v)
        });
        let b_w = symmetric_product(&dk_dc_cos, n, w);
        let neighbours = nearest_neighbours(dirs);
        Ok(RecordRule {
            neighbours,
            spec,
            set,
            factorisation,
            quadrature,
            gls,
            dz_dmu,
            dk_dc,
            dk_dc_cos,
            a_w_u,
            b_w,
        })
    }

    pub fn spec(&self) -> &RecordRuleSpec {
        &self.spec
    }

    /// Local-frame ray directions, in the order `estimate` expects samples.
    pub fn directions(&self) -> &[DVec3] {
        &self.set.directions
    }

    /// The Lambert BMC quadrature (weights, posterior variance of `∫L p`).
    pub fn quadrature(&self) -> &Quadrature {
        &self.quadrature
    }

    /// Irradiance, variance and gradients from one radiance sample per
    /// direction (in [`Self::directions`] order); the sample distances feed
    /// the translation gradient.
    ///
    /// The posterior variance `V` is computed for the kernel's `σ²`, and
    /// `ỸᵀQ⁻¹Ỹ/N` scales as `1/σ²`, so their product — the variance of
    /// `∫L p` with the amplitude fitted to this record's data — does not
    /// depend on the `σ²` chosen; times `π²` for `E = π ∫ L p`.
    pub fn estimate(&self, samples: &[RadianceSample]) -> Result<RecordEstimate, CacheError> {
        let mut one = self.estimate_batch(&[samples]);
        one.pop().expect("one estimate per record")
    }

    /// [`Self::estimate`] of several records, in order. The records share
    /// one solve with `Q` and two matrix products with the derivative
    /// tables, so each `N×N` table is read from memory once per batch: per
    /// record those reads (32 MB at N = 1024) made the products
    /// memory-bound and a fifth of a cached image's time
    /// (docs/BENCHMARKS.md, "Records estimated in batches").
    pub fn estimate_batch(
        &self,
        batch: &[&[RadianceSample]],
    ) -> Vec<Result<RecordEstimate, CacheError>> {
        let n = self.set.len();
        let speeds: Vec<Vec<f64>> = batch
            .iter()
            .map(|s| {
                if s.len() == n {
                    self.boundary_speeds(s)
                } else {
                    Vec::new()
                }
            })
            .collect();
        let inputs: Vec<(&[RadianceSample], &[f64])> = batch
            .iter()
            .copied()
            .zip(speeds.iter().map(Vec::as_slice))
            .collect();
        self.estimate_with_speeds(&inputs)
    }

    /// [`Self::estimate_batch`] with each record's translation speeds `s_i`
    /// given.
    fn estimate_with_speeds(
        &self,
        batch: &[(&[RadianceSample], &[f64])],
    ) -> Vec<Result<RecordEstimate, CacheError>> {
        let n = self.set.len();
        // Column-major `N × 3k`: the centred values `Y − m̂1` of the `k`
        // records that take the BMC rule, three channels each.
        let mut centred = Vec::new();
        let mut stages: Vec<Stage> = batch
            .iter()
            .map(|(samples, _)| match self.centre(samples, &mut centred) {
                Err(e) => Stage::Done(Err(e)),
                Ok(None) => Stage::Done(Ok(self.equal_weight_estimate(samples))),
                Ok(Some(irradiance)) => Stage::Bmc(irradiance),
            })
            .collect();
        let k = centred.len() / (3 * n).max(1);
        if k > 0 {
            // α̃ = Q⁻¹(Y − m̂1), every column in one solve.
            let mut alpha = centred.clone();
            self.factorisation.solve_columns_in_place(&mut alpha, 3 * k);
            // (index in the batch, irradiance) of the BMC records, in order.
            let bmc: Vec<(usize, [f64; 3])> = stages
                .iter()
                .enumerate()
                .filter_map(|(i, stage)| match stage {
                    Stage::Bmc(irradiance) => Some((i, *irradiance)),
                    Stage::Done(_) => None,
                })
                .collect();
            let [a_w_s, b_w_s_u] = self.speed_products(bmc.iter().map(|&(i, _)| batch[i].1));
            for (j, (i, irradiance)) in bmc.into_iter().enumerate() {
                let (samples, speeds) = batch[i];
                let products = SpeedProducts {
                    a_w_s: &a_w_s[j * n..][..n],
                    b_w_s_u: [0, 1].map(|e| &b_w_s_u[(2 * j + e) * n..][..n]),
                };
                stages[i] = Stage::Done(Ok(self.bmc_estimate(
                    irradiance,
                    samples,
                    speeds,
                    channels(&centred, j, n),
                    channels(&alpha, j, n),
                    products,
                )));
            }
        }
        stages
            .into_iter()
            .map(|stage| match stage {
                Stage::Done(result) => result,
                Stage::Bmc(_) => unreachable!("every BMC record was finished"),
            })
            .collect()
    }

    /// Checks one record's samples, appends its centred values `Y − m̂1`
    /// (three columns of `N`) to `centred` and returns its BMC irradiance;
    /// `None` (nothing appended) where that irradiance is negative in a
    /// channel, impossible for non-negative radiance (docs/math.md §3.6).
    fn centre(
        &self,
        samples: &[RadianceSample],
        centred: &mut Vec<f64>,
    ) -> Result<Option<[f64; 3]>, CacheError> {
        let n = self.set.len();
        if samples.len() != n {
            return Err(CacheError::invalid(
                "samples",
                format!("expected {n} radiance samples, got {}", samples.len()),
            ));
        }
        if let Some(bad) = samples.iter().find(|s| !s.radiance.is_finite()) {
            return Err(CacheError::Render(RenderError::NotFinite {
                what: format!("radiance samples ({:?})", bad.radiance),
            }));
        }
        let mut columns = Vec::with_capacity(3 * n);
        let mut irradiance = [0.0; 3];
        for (c, e) in irradiance.iter_mut().enumerate() {
            let y: Vec<f64> = samples.iter().map(|s| s.radiance.to_array()[c]).collect();
            let mean = match self.spec.prior_mean {
                PriorMean::Zero => 0.0,
                // The 4-lane dot of this file.
                PriorMean::Gls => dot(self.gls.ones_solved(), &y) / self.gls.ones_sum(),
            };
            columns.extend(y.iter().map(|v| v - mean));
            *e = PI * self.quadrature.estimate(&y);
        }
        if irradiance.iter().any(|e| *e < 0.0) {
            return Ok(None);
        }
        centred.extend(columns);
        Ok(Some(irradiance))
    }

    /// The BMC record from its irradiance, centred values, `α̃` per channel
    /// and its speeds' products with the derivative tables.
    fn bmc_estimate(
        &self,
        irradiance: [f64; 3],
        samples: &[RadianceSample],
        speeds: &[f64],
        centred: [&[f64]; 3],
        alpha: [&[f64]; 3],
        products: SpeedProducts,
    ) -> RecordEstimate {
        let n = self.set.len();
        let dirs = &self.set.directions;
        let w = &self.quadrature.weights;
        let variance = [0, 1, 2].map(|c| {
            // Maximum likelihood (divisor N), as the marginal-likelihood fit
            // of `bmc::hyperparameters` (docs/math.md §7.3; the per-point
            // estimates of `bmc::estimator` use N − 1 instead).
            let amplitude = (dot(centred[c], alpha[c]) / n as f64).max(0.0);
            // The values' noise is independent across directions.
            let noise: f64 = w
                .iter()
                .zip(samples)
                .map(|(w, s)| w * w * s.variance.to_array()[c].max(0.0))
                .sum();
            PI * PI * (self.quadrature.posterior_variance * amplitude + noise)
        });
        // Rotation about local x and y: δ_i = −a × ω_i is rigid, so dQ = 0
        // and only the kernel-mean term remains; (−a × ω)·ẑ is −ω_y about x
        // and ω_x about y.
        let rotation = [0, 1].map(|axis| {
            let delta_z = |d: &DVec3| if axis == 0 { -d.y } else { d.x };
            self.kernel_mean_term(dirs.iter().map(delta_z), &alpha)
        });
        let translation = self.translation_gradients(speeds, &alpha, products);
        RecordEstimate {
            irradiance: Rgb::from_array(irradiance),
            variance: Rgb::from_array(variance),
            rotation,
            translation,
        }
    }

    /// The fallback of a record whose BMC sum is negative in a channel
    /// (module docs, docs/math.md §3.6): per channel
    /// `E = π (1/N) Σ L_i p(ω_i)/q(ω_i)` with `p = cos θ/π` and `q` the
    /// density of the rule's sample set, its variance `π²` times the sample
    /// variance of the terms over `N`, and no gradients.
    fn equal_weight_estimate(&self, samples: &[RadianceSample]) -> RecordEstimate {
        let pdf = SamplingPdf::of_set(self.spec.samples.kind);
        let (mut irradiance, mut variance) = ([0.0; 3], [0.0; 3]);
        for c in 0..3 {
            let y: Vec<f64> = samples.iter().map(|s| s.radiance.to_array()[c]).collect();
            let e = importance_rule(&Density::Lambert, pdf, &self.set.directions, &y);
            irradiance[c] = PI * e.value;
            variance[c] = PI * PI * e.variance;
        }
        RecordEstimate {
            irradiance: Rgb::from_array(irradiance),
            variance: Rgb::from_array(variance),
            rotation: [Rgb::BLACK; 2],
            translation: [Rgb::BLACK; 2],
        }
    }

    /// The speeds `s_i` of the samples under translation (module docs):
    /// `1/r_i` of the nearest hit among direction `i` and its
    /// [`NEIGHBOURS`] nearest directions, `0` where all escaped. Ward &
    /// Heckbert (1992) move the wall between two neighbouring cells with the
    /// nearer of their two hits, because an occluding edge moves with the
    /// occluder and uncovers or hides what lies behind it; giving each
    /// sample its neighbourhood's largest speed does the same for the
    /// interpolant's transition between a near and a far sample.
    fn boundary_speeds(&self, samples: &[RadianceSample]) -> Vec<f64> {
        let inverse: Vec<f64> = samples
            .iter()
            .map(|s| {
                if s.distance.is_finite() && s.distance > 0.0 {
                    1.0 / s.distance
                } else {
                    0.0
                }
            })
            .collect();
        self.neighbours
            .iter()
            .zip(&inverse)
            .map(|(near, own)| near.iter().fold(*own, |m, &j| m.max(inverse[j])))
            .collect()
    }

    /// `π Σ_i (dz_i/dμ_i) δ_i·ẑ α̃_i`: the kernel-mean part of `π dÎ/dε`
    /// (module docs) for the tangent field's `δ_i·ẑ`.
    fn kernel_mean_term(&self, delta_z: impl Iterator<Item = f64>, alpha: &[&[f64]; 3]) -> Rgb {
        let mut out = [0.0; 3];
        for (i, dz) in delta_z.enumerate() {
            let dz = self.dz_dmu[i] * dz;
            for c in 0..3 {
                out[c] += dz * alpha[c][i];
            }
        }
        Rgb::from_array(out.map(|v| PI * v))
    }

    /// `A(w∘s)` (column-major `N × k`) and `B(w∘s∘u_e)` (`N × 2k`, local x
    /// then y for each record) for the speeds `s` of `k` records, as
    /// [`Self::translation_gradients`] needs them.
    fn speed_products<'a>(&self, speeds: impl Iterator<Item = &'a [f64]>) -> [Vec<f64>; 2] {
        let (n, dirs) = (self.set.len(), &self.set.directions);
        let w = &self.quadrature.weights;
        let (mut w_s, mut w_s_u) = (Vec::new(), Vec::new());
        for s in speeds {
            let start = w_s.len();
            w_s.extend(w.iter().zip(s).map(|(w, s)| w * s));
            for e in 0..2 {
                w_s_u.extend(w_s[start..].iter().zip(dirs).map(|(x, d)| x * d[e]));
            }
        }
        [
            symmetric_product(&self.dk_dc, n, &w_s),
            symmetric_product(&self.dk_dc_cos, n, &w_s_u),
        ]
    }

    /// `π dÎ/dε` for translations along local x and y (module docs), with
    /// `s_i = 1/r_i`. With `u_i = e·ω_i`, `δ_i = −s_i (e − u_i ω_i)` and
    /// `C_ij = ω_i·ω_j`, the `dQ` term
    /// `Σ_ij w_i A_ij (δ_i·ω_j + ω_i·δ_j) α̃_j` expands into
    /// `−(A(w∘s))·(α̃∘u) + (B(w∘s∘u))·α̃ − (A(w∘u))·(α̃∘s) + (Bw)·(α̃∘s∘u)`
    /// (`A`, `B = A∘C` symmetric), so a record needs three products of a
    /// table with a vector ([`Self::speed_products`], for a whole batch at
    /// once), not a double loop per channel and axis.
    fn translation_gradients(
        &self,
        s: &[f64],
        alpha: &[&[f64]; 3],
        products: SpeedProducts,
    ) -> [Rgb; 2] {
        let dirs = &self.set.directions;
        let SpeedProducts { a_w_s, b_w_s_u } = products;
        let u = [0, 1].map(|e| dirs.iter().map(|d| d[e]).collect::<Vec<f64>>());
        [0, 1].map(|e| {
            let (u, b_w_s_u) = (&u[e], &b_w_s_u[e]);
            // δ_i·ẑ = s_i u_i ω_i,z (e has no z component).
            let delta_z = dirs.iter().zip(s).map(|(d, s)| s * d[e] * d.z);
            let mean_term = self.kernel_mean_term(delta_z, alpha).to_array();
            let mut out = [0.0; 3];
            for c in 0..3 {
                let a = alpha[c];
                let mut sum = 0.0;
                for i in 0..dirs.len() {
                    sum += -a_w_s[i] * a[i] * u[i] + b_w_s_u[i] * a[i]
                        - self.a_w_u[e][i] * a[i] * s[i]
                        + self.b_w[i] * a[i] * s[i] * u[i];
                }
                out[c] = mean_term[c] - PI * sum;
            }
            Rgb::from_array(out)
        })
    }
}

/// Neighbourhood size of the translation speeds ([`RecordRule::boundary_speeds`]):
/// points of a spherical Fibonacci set have about six Delaunay neighbours.
const NEIGHBOURS: usize = 6;

/// For each direction, the indices of the [`NEIGHBOURS`] others with the
/// largest dot product (itself repeated when there are fewer others).
fn nearest_neighbours(dirs: &[DVec3]) -> Vec<[usize; NEIGHBOURS]> {
    (0..dirs.len())
        .map(|i| {
            // (dot, index), best first; insertion keeps the k best.
            let mut best: Vec<(f64, usize)> = Vec::with_capacity(NEIGHBOURS + 1);
            for (j, d) in dirs.iter().enumerate() {
                if j == i {
                    continue;
                }
                let c = d.dot(dirs[i]);
                if best.len() == NEIGHBOURS && c <= best[NEIGHBOURS - 1].0 {
                    continue;
                }
                let at = best.partition_point(|&(b, _)| b >= c);
                best.insert(at, (c, j));
                best.truncate(NEIGHBOURS);
            }
            let mut out = [i; NEIGHBOURS];
            for (slot, (_, j)) in out.iter_mut().zip(best) {
                *slot = j;
            }
            out
        })
        .collect()
}

/// A record between its centring and its BMC estimate
/// ([`RecordRule::estimate_batch`]).
enum Stage {
    /// Takes the BMC rule; its irradiance per channel.
    Bmc([f64; 3]),
    /// Invalid, or answered by the equal-weight fallback.
    Done(Result<RecordEstimate, CacheError>),
}

/// Record `j`'s three channel columns of a column-major `N × 3k` matrix.
fn channels(m: &[f64], j: usize, n: usize) -> [&[f64]; 3] {
    [0, 1, 2].map(|c| &m[(3 * j + c) * n..][..n])
}

/// One record's columns of [`RecordRule::speed_products`].
#[derive(Clone, Copy)]
struct SpeedProducts<'a> {
    /// `A(w∘s)`.
    a_w_s: &'a [f64],
    /// `B(w∘s∘u_e)` for local x and y.
    b_w_s_u: [&'a [f64]; 2],
}

/// `∂k/∂c` with `c = ω·ω'` for chordal distance `d = sqrt(2 − 2c) > 0`
/// (`∂d/∂c = −1/d`, differentiating the forms in `bmc::kernel`):
/// SE `k/ℓ²`; Matérn 3/2 `3σ² e^{−s}/ℓ²` (`s = √3 d/ℓ`);
/// Matérn 5/2 `5σ²(1 + s) e^{−s}/(3ℓ²)` (`s = √5 d/ℓ`).
fn kernel_slope(kernel: &Kernel, d: f64) -> f64 {
    let l2 = kernel.lengthscale * kernel.lengthscale;
    match kernel.kind {
        KernelKind::SquaredExponential => kernel.eval_chord(d) / l2,
        KernelKind::Matern32 => {
            let s = 3f64.sqrt() * d / kernel.lengthscale;
            3.0 * kernel.variance * (-s).exp() / l2
        }
        KernelKind::Matern52 => {
            let s = 5f64.sqrt() * d / kernel.lengthscale;
            5.0 * kernel.variance * (1.0 + s) * (-s).exp() / (3.0 * l2)
        }
    }
}

/// `dz/dμ` at each direction's `μ = cos θ` by central differences of the
/// exact Lambert kernel means (relative accuracy ~1e-12, so a step of 1e-5
/// leaves ~1e-7 relative error); one-sided at `μ = 1`.
fn kernel_mean_slopes(directions: &[DVec3], kernel: &Kernel) -> Result<Vec<f64>, CacheError> {
    const STEP: f64 = 1e-5;
    let at = |mu: f64| DVec3::new((1.0 - mu * mu).max(0.0).sqrt(), 0.0, mu);
    let mut probes = Vec::with_capacity(2 * directions.len());
    let mut steps = Vec::with_capacity(directions.len());
    for d in directions {
        let mu = d.z.clamp(-1.0, 1.0);
        let h = STEP.min(0.5 * (1.0 - mu));
        let (hi, lo) = if h > 1e-9 {
            (mu + h, mu - h)
        } else {
            (mu, mu - STEP)
        };
        probes.push(at(hi));
        probes.push(at(lo));
        steps.push(hi - lo);
    }
    let z = kernel_means(&probes, kernel, &Density::Lambert, KernelMeanMethod::Exact)?;
    Ok(steps
        .iter()
        .enumerate()
        .map(|(i, h)| (z[2 * i] - z[2 * i + 1]) / h)
        .collect())
}

#[cfg(test)]
mod tests;
