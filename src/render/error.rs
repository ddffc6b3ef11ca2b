//! What can stop an encoder: a format's size limit, or a bug in the
//! geometry handed to it. Encoders get finished, checked trees; these are
//! rare and always reported, never written as a broken file.

use crate::error::Error;

/// Why a file could not be encoded.
#[derive(Debug, thiserror::Error)]
pub enum RenderError {
    /// A count beyond what the format's indices or lengths hold.
    #[error("{0}")]
    TooLarge(&'static str),
    /// The geometry is not what the encoder was promised.
    #[error("{0}")]
    Inconsistent(String),
    /// JSON serialisation failed.
    #[error("JSON: {0}")]
    Json(#[from] serde_json::Error),
    /// glTF JSON serialisation failed.
    #[error("glTF JSON: {0}")]
    Gltf(String),
    /// PNG encoding failed.
    #[error("PNG: {0}")]
    Png(#[from] png::EncodingError),
}

impl From<RenderError> for Error {
    fn from(e: RenderError) -> Self {
        Error::Stage {
            stage: "output",
            source: Box::new(e),
        }
    }
}
