//! The bus's one error type, apart from the bus so that the modules the
//! bus uses (service names) can return it without importing the bus.

#[derive(Debug, thiserror::Error)]
pub enum BusError {
    #[error("invalid swarm name `{0}`: use letters, digits, `-` and `_` (at most 32)")]
    InvalidSwarm(String),
    /// What iceoryx2 refused, with its own error as the source (shown by
    /// `{:#}` of an `anyhow::Error`, or by walking `source()`).
    #[error("bus: {what}")]
    Iceoryx {
        what: String,
        source: Box<dyn std::error::Error + Send + Sync>,
    },
}

impl BusError {
    pub fn iceoryx(
        what: impl Into<String>,
        source: impl std::error::Error + Send + Sync + 'static,
    ) -> Self {
        Self::Iceoryx {
            what: what.into(),
            source: Box::new(source),
        }
    }
}
