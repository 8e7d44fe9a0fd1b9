//! Logging shim.
//!
//! On the target the macros forward to `defmt`; on the host they compile to nothing (the
//! arguments are still type-checked, so a log call that would not build for the target does not
//! build for the host either). Library code logs only through these macros.

#[cfg(target_os = "none")]
#[doc(hidden)]
pub use defmt as __defmt;

/// Logs at `trace` level (defmt on the target, nothing on the host).
#[macro_export]
macro_rules! trace {
    ($($arg:tt)*) => {{
        #[cfg(target_os = "none")]
        $crate::fmt::__defmt::trace!($($arg)*);
        #[cfg(not(target_os = "none"))]
        { let _ = || { $crate::__host_log_args!($($arg)*); }; }
    }};
}

/// Logs at `info` level (defmt on the target, nothing on the host).
#[macro_export]
macro_rules! info {
    ($($arg:tt)*) => {{
        #[cfg(target_os = "none")]
        $crate::fmt::__defmt::info!($($arg)*);
        #[cfg(not(target_os = "none"))]
        { let _ = || { $crate::__host_log_args!($($arg)*); }; }
    }};
}

/// Logs at `warn` level (defmt on the target, nothing on the host).
#[macro_export]
macro_rules! warn {
    ($($arg:tt)*) => {{
        #[cfg(target_os = "none")]
        $crate::fmt::__defmt::warn!($($arg)*);
        #[cfg(not(target_os = "none"))]
        { let _ = || { $crate::__host_log_args!($($arg)*); }; }
    }};
}

/// Logs at `error` level (defmt on the target, nothing on the host).
#[macro_export]
macro_rules! error {
    ($($arg:tt)*) => {{
        #[cfg(target_os = "none")]
        $crate::fmt::__defmt::error!($($arg)*);
        #[cfg(not(target_os = "none"))]
        { let _ = || { $crate::__host_log_args!($($arg)*); }; }
    }};
}

/// Evaluates nothing at run time but keeps the log arguments "used" on the host.
#[doc(hidden)]
#[macro_export]
macro_rules! __host_log_args {
    ($fmt:literal $(, $arg:expr)* $(,)?) => {{
        $( let _ = &$arg; )*
    }};
}
