//! [`DynTracer`]: an object-safe view of any `Tracer`, so one case body drives every
//! backend through `&mut dyn DynTracer`. It lives in the facade's registry
//! (`arpa::backends`), which creates the backends the suite runs on.

pub use arpa::backends::{BoxError, DynTracer};
