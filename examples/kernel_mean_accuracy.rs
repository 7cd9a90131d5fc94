//! Measures the error of the spherical-Gaussian kernel means (Marques et al.
//! 2013) against the exact ones, for the "Kernel-mean accuracy" section of
//! `docs/BENCHMARKS.md`:
//!
//! `cargo run --release --example kernel_mean_accuracy`
//!
//! For each case: the largest error of `z_i` relative to `max_j z_j` over a
//! 128-point spherical Fibonacci set, the median per-element relative error,
//! and the relative error of `V₀`.

use bmc_irradiance::bmc::{
    Density, Kernel, KernelKind, KernelMeanMethod, kernel_means, prior_variance,
};
use bmc_irradiance::sphere::{SampleSet, SampleSetKind, SampleSetSpec};

fn main() -> anyhow::Result<()> {
    let set = SampleSet::generate(SampleSetSpec {
        kind: SampleSetKind::Fibonacci,
        count: 128,
        seed: 0,
    })?;
    let densities = [
        ("uniform", Density::Uniform),
        ("lambert", Density::Lambert),
        (
            "phong m=10 θr=0",
            Density::Phong {
                exponent: 10.0,
                mirror_elevation: 0.0,
            },
        ),
        (
            "phong m=10 θr=1.2",
            Density::Phong {
                exponent: 10.0,
                mirror_elevation: 1.2,
            },
        ),
        (
            "phong m=100 θr=0.6",
            Density::Phong {
                exponent: 100.0,
                mirror_elevation: 0.6,
            },
        ),
        (
            "phong m=1000 θr=0.6",
            Density::Phong {
                exponent: 1000.0,
                mirror_elevation: 0.6,
            },
        ),
    ];
    println!("| density | ℓ | max abs err / max z | median rel err of z | rel err of V₀ |");
    println!("|---|---|---|---|---|");
    for (name, density) in densities {
        for ell in [0.1, 0.25, 0.5, 1.0, 2.0] {
            let kernel = Kernel::new(KernelKind::SquaredExponential, ell, 1.0, 0.0)?;
            let exact = kernel_means(&set.directions, &kernel, &density, KernelMeanMethod::Exact)?;
            let sg = kernel_means(
                &set.directions,
                &kernel,
                &density,
                KernelMeanMethod::SphericalGaussian,
            )?;
            let zmax = exact.iter().fold(0.0f64, |a, b| a.max(*b));
            let max_err = exact
                .iter()
                .zip(&sg)
                .map(|(e, s)| (e - s).abs())
                .fold(0.0f64, f64::max)
                / zmax;
            let mut rel: Vec<f64> = exact
                .iter()
                .zip(&sg)
                .map(|(e, s)| ((s - e) / e).abs())
                .collect();
            rel.sort_by(f64::total_cmp);
            let median = rel[rel.len() / 2];
            let v_exact = prior_variance(&kernel, &density, KernelMeanMethod::Exact)?;
            let v_sg = prior_variance(&kernel, &density, KernelMeanMethod::SphericalGaussian)?;
            println!(
                "| {name} | {ell} | {max_err:.2e} | {median:.2e} | {:.2e} |",
                (v_sg / v_exact - 1.0).abs()
            );
        }
    }
    Ok(())
}
