//! How a record's rays gather their incident radiance, as values: by paths,
//! by an ambient bounce through the integrator's cache, or through the
//! secondary cache ([`Gather`], and the choice among them per record level,
//! [`Gather::for_record`]), and how many estimates each direction averages
//! ([`RecordGather`]). The gathering itself ([`RecordGather::samples`]) is
//! part of the shading/record recursion and stays in `shade.rs`.

use super::CachedIntegrator;
use crate::integrator::cached::config::AMBIENT_MIN_DEPTH;
use crate::integrator::cached::shade_point::{Bounce, OnMiss};
use crate::render::{AveragedPaths, PathLimits};

/// Where a record's rays get their incident radiance.
#[derive(Clone, Copy)]
pub enum Gather<'a> {
    /// One path-traced estimate per ray ([`Transport::hemisphere_samples`](crate::render::Transport::hemisphere_samples)).
    Paths,
    /// An ambient bounce through `integrator`'s cache (module docs): at each
    /// ray's hit, direct light by one light sample plus `(k_d/π) E_ind` from
    /// the cache, with `bounce.on_miss` where no record covers the hit.
    Cache {
        integrator: CachedIntegrator<'a>,
        bounce: Bounce,
    },
    /// Each ray traced to its first hit `y` once and `y` shaded through a
    /// frozen cache, `integrator`'s (the `secondary` module): direct light
    /// by [`RecordGather::per_direction`] stratified light samples,
    /// `(k_d/π) E_ind(y)` looked up at the integrator's accuracy, glossy
    /// lobes by one lobe-sampled path; where no record covers `y`, one path
    /// ([`OnMiss::PathTrace`]). The cache is only read.
    Secondary { integrator: CachedIntegrator<'a> },
}

impl<'a> Gather<'a> {
    /// How a record at `level` gathers: through the integrator's secondary
    /// cache if it has one and `paths` reach [`AMBIENT_MIN_DEPTH`] (the
    /// options exclude ambient bounces then); through the integrator's cache
    /// while `level < ambient_bounces` and `paths` reach it; by paths
    /// otherwise. With `insert_nested` a miss at a bounce creates a
    /// record one level deeper; without it the cache is only read (a
    /// fallback path serves the miss), which keeps a placement batch
    /// deterministic.
    pub fn for_record(
        integrator: CachedIntegrator<'a>,
        paths: PathLimits,
        level: u32,
        insert_nested: bool,
    ) -> Self {
        if paths.max_depth < AMBIENT_MIN_DEPTH {
            return Gather::Paths;
        }
        if let Some(cache) = integrator.secondary {
            let integrator = CachedIntegrator {
                cache,
                secondary: None,
                ..integrator
            };
            return Gather::Secondary { integrator };
        }
        if level >= integrator.shading.options.ambient_bounces {
            return Gather::Paths;
        }
        let on_miss = if insert_nested {
            OnMiss::Insert
        } else {
            OnMiss::PathTrace
        };
        Gather::Cache {
            integrator,
            bounce: Bounce {
                paths,
                level,
                on_miss,
            },
        }
    }
}

/// How a record's rays gather, and how many estimates each direction averages.
#[derive(Clone, Copy)]
pub struct RecordGather<'a> {
    /// The paths the rays sum.
    pub paths: PathLimits,
    /// Estimates averaged per direction (≥ 1); by paths, those share their
    /// first segment; through the secondary cache, the light samples at it.
    pub per_direction: u32,
    pub gather: Gather<'a>,
}

impl RecordGather<'_> {
    /// The paths each direction averages when gathering by paths.
    pub(super) fn averaged_paths(&self) -> AveragedPaths {
        AveragedPaths {
            limits: self.paths,
            per_direction: self.per_direction,
        }
    }
}
