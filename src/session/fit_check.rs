//! Whether the measured runs fit the exact result at all (`calibrate`'s fit line, `apply`'s
//! confirmation), and which consistent measuring mistake explains a poor fit (`convention`).
//!
//! The χ² is [`FitCheck`]'s, over the runs the robust fit kept (a flagged run is the
//! `DISAGREES` flow's); the mistakes are the [`Convention`]s, each tried by re-reading every
//! measured run and fitting again.

use core::fmt::{self, Write};

use super::traits::{Calibrator, Reading};
use crate::calibration::fit_check::FitCheck;
use crate::kinematics::geometry::Geometry;
use crate::motion::convention::Convention;
use crate::motion::run::RunRecord;
use crate::protocol::EOL;
use crate::protocol::token::{FIT, MISTAKE, NO_MISTAKE, POOR_FIT};
use crate::util::decimal::{Decimal, Scientific};

/// The method whose residuals the fit check reads.
pub(super) const CHECKED_METHOD: &str = "exact";

/// The mistaken convention (other than `current`'s) under which every run fits best, if one
/// fits within the noise; the calibrator reads the runs as `current` again afterwards.
pub(super) fn name_mistake<C: Calibrator>(
    calibrator: &mut C,
    runs: &[RunRecord],
    nominal: &Geometry,
    current: Reading,
) -> Option<(Convention, FitCheck)> {
    let mut best: Option<(Convention, FitCheck)> = None;
    for c in Convention::ALL {
        if c == current.convention {
            continue;
        }
        calibrator.set_reading(Reading {
            convention: c,
            ..current
        });
        if let Some(check) = calibrator.fit_check(runs, nominal)
            && !check.poor()
            && best.is_none_or(|(_, b)| check.chi2 < b.chi2)
        {
            best = Some((c, check));
        }
    }
    calibrator.set_reading(current);
    best
}

/// ` chi2=… dof=… p=…`.
fn write_numbers(out: &mut dyn Write, check: &FitCheck) -> fmt::Result {
    write!(
        out,
        "chi2={} dof={} p={}",
        Decimal::fixed(check.chi2, 1),
        check.dof,
        Scientific::new(check.probability, 2)
    )
}

/// The fit line: `fit exact chi2=… dof=… p=…: ok|POOR FIT, apply needs yes` (the noise
/// assumed is `params`' `measure_sd`, `heading_sd`), and for a poor fit the mistake line after
/// it (`mistake`: the convention that fits, if one does).
pub(super) fn write_fit(
    out: &mut dyn Write,
    check: &FitCheck,
    mistake: Option<(Convention, FitCheck)>,
) -> fmt::Result {
    write!(out, "  {FIT}{CHECKED_METHOD} ")?;
    write_numbers(out, check)?;
    out.write_str(": ")?;
    out.write_str(if check.poor() { POOR_FIT } else { "ok" })?;
    if !check.poor() {
        return out.write_str(EOL);
    }
    write!(out, ", apply needs yes{EOL}  {MISTAKE}")?;
    match mistake {
        Some((c, fits)) => {
            write!(out, "{}: {} fits (", c.as_str(), c.describe())?;
            write_numbers(out, &fits)?;
            write!(out, "): convention {} re-reads the runs{EOL}", c.as_str())
        }
        None => write!(
            out,
            "{NO_MISTAKE}: measure again, declare measure_sd/heading_sd, or apply <method> yes{EOL}"
        ),
    }
}
