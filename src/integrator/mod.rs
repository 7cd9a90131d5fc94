//! Integrators: how a camera ray or a query becomes a radiance estimate. Path
//! tracing lives with the light-transport kernels in [`crate::render`]; the
//! irradiance-cache integrator, which reads and extends the record store of
//! [`crate::cache`], is [`cached`].

pub mod cached;
