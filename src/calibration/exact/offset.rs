//! The end offset: a bias of the measured end position common to the closed paths of one kind
//! and size, eliminated from the fit by projection (see the `exact` module docs, *End offset*).
//!
//! For fixed factors the offset that fits a group best is the weighted mean of its runs' x and y
//! residuals, so the fit minimises the residuals *about* that mean: the cost loses
//! `(Σ w r)² / Σ w` per group and position channel, the normal equations `(Σ w J)(Σ w J)ᵀ / Σ w`
//! and `(Σ w J)(Σ w r) / Σ w`. That is the fit with the two offsets of every group as free
//! parameters, solved for them in closed form (variable projection).

use super::problem::{CHANNELS, Precision, Problem, Residuals, X, Y};
use super::robust::{Weight, weight};
use crate::calibration::RunObservation;
use crate::kinematics::reference::ArcModel;
use crate::motion::run::{Direction, PathKind};

/// Most groups with an offset of their own; runs of further groups are fitted without one.
pub(super) const MAX_GROUPS: usize = 4;

/// The groups of runs that share an end offset: closed paths (squares, circles) measured at
/// their end with their heading, each group of one kind and size (peers of its first run) with
/// runs in both turn directions.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(super) struct Groups {
    /// Index of the first run of each group.
    first: [usize; MAX_GROUPS],
    count: usize,
}

/// Weighted sums of one set of parameters' residual rows (and, for the normal equations, their
/// Jacobian rows) per group and position channel.
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct Sums {
    w: [[f64; 2]; MAX_GROUPS],
    wr: [[f64; 2]; MAX_GROUPS],
    wj: [[[f64; 3]; 2]; MAX_GROUPS],
}

impl Sums {
    /// Adds a position row of channel `c` (x or y) of a run of group `g`: weight `w`, residual
    /// `r`, Jacobian row `j`.
    pub(super) fn add(&mut self, g: usize, c: usize, w: f64, r: f64, j: &[f64; 3]) {
        let k = usize::from(c == Y);
        self.w[g][k] += w;
        self.wr[g][k] += w * r;
        for (s, v) in self.wj[g][k].iter_mut().zip(j) {
            *s += w * v;
        }
    }

    /// The groups' offsets `(x, y)`, metres: the weighted mean residuals.
    pub(super) fn offsets(&self) -> [[f64; 2]; MAX_GROUPS] {
        let mut o = [[0.0; 2]; MAX_GROUPS];
        for (g, og) in o.iter_mut().enumerate() {
            for (k, v) in og.iter_mut().enumerate() {
                if self.w[g][k] > 0.0 {
                    *v = self.wr[g][k] / self.w[g][k];
                }
            }
        }
        o
    }

    /// Adds the x and y rows `rows` of an end-pose run of group `g` with its weights `w`, for
    /// the offsets and the cost only (no Jacobian).
    pub(super) fn add_position(&mut self, g: usize, w: Weight, rows: &[f64; CHANNELS]) {
        self.add(g, X, w.row(X), rows[X], &[0.0; 3]);
        self.add(g, Y, w.row(Y), rows[Y], &[0.0; 3]);
    }

    /// What the offsets take off the weighted sum of squares.
    pub(super) fn cost_reduction(&self) -> f64 {
        let mut s = 0.0;
        for g in 0..MAX_GROUPS {
            for k in 0..2 {
                if self.w[g][k] > 0.0 {
                    s += self.wr[g][k] * self.wr[g][k] / self.w[g][k];
                }
            }
        }
        s
    }

    /// Projects the offsets out of the normal equations `a`, `g` (first `n` parameters).
    pub(super) fn project(&self, a: &mut [[f64; 3]; 3], grad: &mut [f64; 3], n: usize) {
        for gi in 0..MAX_GROUPS {
            for k in 0..2 {
                let w = self.w[gi][k];
                if w <= 0.0 {
                    continue;
                }
                let (wj, wr) = (&self.wj[gi][k], self.wr[gi][k]);
                for e in 0..n {
                    grad[e] -= wj[e] * wr / w;
                    for f in 0..n {
                        a[e][f] -= wj[e] * wj[f] / w;
                    }
                }
            }
        }
    }
}

fn direction(run: &RunObservation<'_>) -> Option<Direction> {
    match run.path {
        PathKind::Square { direction, .. } | PathKind::Circle { direction, .. } => Some(direction),
        PathKind::Line { .. } => None,
    }
}

impl Groups {
    /// Number of groups.
    pub(super) fn count(&self) -> usize {
        self.count
    }

    /// Index of the first run of group `g`.
    pub(super) fn first(&self, g: usize) -> usize {
        self.first[g]
    }
}

impl Problem<'_, '_> {
    /// Whether `run` can share an end offset: a closed path measured at its end, heading
    /// included.
    fn offset_candidate(&self, run: &RunObservation<'_>) -> bool {
        Self::usable(run)
            && !Self::is_path(run)
            && direction(run).is_some()
            && self.heading(run).is_some()
    }

    /// The groups of `self.runs` that get an offset (none unless
    /// [`ExactOptions::end_offset`](super::ExactOptions::end_offset)).
    pub(super) fn offset_groups(&self) -> Groups {
        let mut groups = Groups::default();
        if !self.options.end_offset {
            return groups;
        }
        // Candidate groups, by the first run of each kind and size.
        let mut first = [0; MAX_GROUPS];
        let mut directions = [[false; 2]; MAX_GROUPS];
        let mut count = 0;
        for (i, run) in self.runs.iter().enumerate() {
            if !self.offset_candidate(run) {
                continue;
            }
            let g = (0..count).find(|&g| Self::peers(&self.runs[first[g]], run));
            let g = match g {
                Some(g) => g,
                None if count < MAX_GROUPS => {
                    first[count] = i;
                    count += 1;
                    count - 1
                }
                None => continue,
            };
            let d = usize::from(direction(run) == Some(Direction::Ccw));
            directions[g][d] = true;
        }
        // Only groups with both turn directions: the offset is what CW and CCW runs share.
        for g in 0..count {
            if directions[g] == [true, true] {
                groups.first[groups.count] = first[g];
                groups.count += 1;
            }
        }
        groups
    }

    /// The group of `run` in `self.groups`, if it shares an offset.
    pub(super) fn group(&self, run: &RunObservation<'_>) -> Option<usize> {
        let groups = &self.groups;
        if groups.count == 0 || !self.offset_candidate(run) {
            return None;
        }
        (0..groups.count).find(|&g| Self::peers(&self.runs[groups.first[g]], run))
    }

    /// The signed residual rows of end-pose run `i` for `model`: those kept in `known`, or one
    /// `f64` pass.
    pub(super) fn end_rows(
        &self,
        i: usize,
        run: &RunObservation<'_>,
        known: Option<&Residuals>,
        model: &ArcModel,
    ) -> [f64; CHANNELS] {
        match Self::kept(i, run, known) {
            Some(k) => k.rows,
            None => self.end_pass(run, model, Precision::F64).rows,
        }
    }

    /// The offsets of `self.groups` for `model` (residual rows kept in `known` where there are)
    /// and the weights `weights`.
    pub(super) fn offsets(
        &self,
        weights: Option<&[Weight]>,
        known: Option<&Residuals>,
        model: &ArcModel,
    ) -> [[f64; 2]; MAX_GROUPS] {
        let mut sums = Sums::default();
        for (i, run) in self.runs.iter().enumerate() {
            if let Some(g) = self.group(run) {
                sums.add_position(g, weight(weights, i), &self.end_rows(i, run, known, model));
            }
        }
        sums.offsets()
    }
}
