//! The error type of the registry and its kernel runners, below both so each can name it.

/// A backend's error, boxed (the backend's own `thiserror` enum inside).
pub type BoxError = Box<dyn std::error::Error + Send + Sync + 'static>;
