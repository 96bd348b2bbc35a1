//! Errors as Python exceptions, with the command line's one-line messages.

use pyo3::exceptions::{
    PyFileNotFoundError, PyMemoryError, PyOSError, PyPermissionError, PyRuntimeError, PyValueError,
};
use pyo3::prelude::*;

use pathdensity_core::pipeline::PipelineError;

/// The one-line message of a format error (it names the file) as the
/// matching `OSError`.
pub(crate) fn os_error(e: pathdensity_format::Error) -> PyErr {
    let message = e.to_string();
    match &e {
        pathdensity_format::Error::Io { error, .. } => match error.kind() {
            std::io::ErrorKind::NotFound => PyFileNotFoundError::new_err(message),
            std::io::ErrorKind::PermissionDenied => PyPermissionError::new_err(message),
            _ => PyOSError::new_err(message),
        },
        pathdensity_format::Error::Format { .. } => PyOSError::new_err(message),
    }
}

/// A pipeline refusal as Python's exception for it; the message is the
/// command line's (a configuration field is named as the keyword).
pub(crate) fn pipeline_error(e: PipelineError) -> PyErr {
    let message = e.to_string();
    match e {
        PipelineError::Config(_) | PipelineError::NoValidSample | PipelineError::NoWhite => {
            PyValueError::new_err(message)
        }
        PipelineError::Memory { .. } => PyMemoryError::new_err(message),
        PipelineError::Threads(_) | PipelineError::Method { .. } => {
            PyRuntimeError::new_err(message)
        }
    }
}

pub(crate) fn value_error(message: impl Into<String>) -> PyErr {
    PyValueError::new_err(message.into())
}
