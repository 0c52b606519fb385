//! Rust errors as Python exceptions.
//!
//! Bad input (a world file, a state description, a name the world does not have, an
//! argument out of range) raises `ValueError` with the same one sentence the command
//! line prints before it exits 2. The service client's errors are typed, one class per
//! kind of failure, all subclasses of `fulcrum.ServiceError`.

use fulcrum_empowerment::service::ClientError;
use fulcrum_empowerment::EngineError;
use fulcrum_world::{DescribeError, WorldError};
use pyo3::create_exception;
use pyo3::exceptions::{PyRuntimeError, PyValueError};
use pyo3::prelude::*;

create_exception!(
    fulcrum,
    ServiceError,
    PyRuntimeError,
    "The empowerment service could not answer."
);
create_exception!(
    fulcrum,
    NoService,
    ServiceError,
    "No service for the namespace answered before the deadline."
);
create_exception!(
    fulcrum,
    WrongWorld,
    ServiceError,
    "The service serves another world than the client's."
);
create_exception!(
    fulcrum,
    ServiceTimeout,
    ServiceError,
    "A request got no answer in time."
);
create_exception!(
    fulcrum,
    ServiceFull,
    ServiceError,
    "The service has as many clients as it takes (`fulcrum serve --max-clients`)."
);
create_exception!(
    fulcrum,
    ServiceGone,
    ServiceError,
    "The service went away with requests in flight."
);
create_exception!(
    fulcrum,
    Refused,
    ServiceError,
    "The service refused the request (its status says why)."
);
create_exception!(
    fulcrum,
    TransportError,
    ServiceError,
    "Shared memory (iceoryx2) failed."
);

/// Adds the exception classes to the module.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    let py = m.py();
    m.add("ServiceError", py.get_type::<ServiceError>())?;
    m.add("NoService", py.get_type::<NoService>())?;
    m.add("WrongWorld", py.get_type::<WrongWorld>())?;
    m.add("ServiceTimeout", py.get_type::<ServiceTimeout>())?;
    m.add("ServiceFull", py.get_type::<ServiceFull>())?;
    m.add("ServiceGone", py.get_type::<ServiceGone>())?;
    m.add("Refused", py.get_type::<Refused>())?;
    m.add("TransportError", py.get_type::<TransportError>())?;
    Ok(())
}

/// A `ValueError` with this sentence.
pub fn value_error(msg: impl Into<String>) -> PyErr {
    PyValueError::new_err(msg.into())
}

/// Everything that is the caller's mistake becomes a `ValueError` with its sentence.
pub trait IntoPy<T> {
    /// The result, its error as a Python exception.
    fn py_err(self) -> PyResult<T>;
}

impl<T> IntoPy<T> for Result<T, WorldError> {
    fn py_err(self) -> PyResult<T> {
        self.map_err(|e| value_error(e.to_string()))
    }
}

impl<T> IntoPy<T> for Result<T, DescribeError> {
    fn py_err(self) -> PyResult<T> {
        self.map_err(|e| value_error(e.to_string()))
    }
}

impl<T> IntoPy<T> for Result<T, EngineError> {
    fn py_err(self) -> PyResult<T> {
        self.map_err(|e| value_error(e.to_string()))
    }
}

impl<T> IntoPy<T> for Result<T, ClientError> {
    fn py_err(self) -> PyResult<T> {
        self.map_err(|e| {
            let msg = e.to_string();
            match e {
                ClientError::NoService { .. } => NoService::new_err(msg),
                ClientError::WrongWorld { .. } => WrongWorld::new_err(msg),
                ClientError::Timeout(_) => ServiceTimeout::new_err(msg),
                ClientError::ServiceGone => ServiceGone::new_err(msg),
                ClientError::Refused(_) => Refused::new_err(msg),
                ClientError::Full { .. } => ServiceFull::new_err(msg),
                ClientError::Ipc(_) | ClientError::Transport { .. } => TransportError::new_err(msg),
            }
        })
    }
}
