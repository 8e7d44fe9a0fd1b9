//! The robust weighting: per-run Cauchy weights and per-channel weights from the scatter of each
//! run's peers (see the module docs of [`super`], *Robust fit*).

use super::problem::{CHANNELS, HEADING, Problem, Residuals, X, Y, squares};
use super::{
    CAUCHY_C, CHANNEL_TOLERANCE, MAX_WEIGHTED_RUNS, MIN_CHANNEL_PEERS, MIN_PEERS,
    PEER_LENGTH_RATIO, WEIGHT_TOLERANCE,
};
use crate::calibration::RunObservation;
use crate::kinematics::reference::ArcModel;
use crate::util::num::{fmax, fmin};

/// Median of χ² with `k` degrees of freedom, `k` = 1, 2, 3.
fn chi2_median(k: usize) -> f64 {
    match k {
        1 => 0.454_936_423_119_572_8,
        2 => core::f64::consts::LN_2 * 2.0,
        _ => 2.365_973_884_375_338,
    }
}

/// Median of a non-empty slice (sorts it).
///
/// An insertion sort: the slices hold one value per run (at most [`MAX_WEIGHTED_RUNS`]), where
/// its few hundred comparisons cost nothing beside one re-integration, and it is 60 bytes of code
/// where `sort_unstable_by` brings about 3 KiB to the firmware. The median does not depend on the
/// sort: `total_cmp` orders equal values only when their bits are equal.
fn median(v: &mut [f64]) -> f64 {
    for i in 1..v.len() {
        let mut j = i;
        while j > 0 && v[j - 1].total_cmp(&v[j]).is_gt() {
            v.swap(j - 1, j);
            j -= 1;
        }
    }
    let n = v.len();
    if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    }
}

/// The weights of one run in the fit: its robust weight and the relative weight of its heading
/// row against its position rows (the channel weight, see the `exact` module docs).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct Weight {
    pub(super) run: f64,
    pub(super) channel: [f64; CHANNELS],
}

impl Weight {
    pub(super) const ONE: Weight = Weight {
        run: 1.0,
        channel: [1.0; CHANNELS],
    };

    /// The weight of a residual row of channel `c`.
    pub(super) fn row(self, c: usize) -> f64 {
        self.run * self.channel[c]
    }
}

/// Weights of run `i`: 1 without weights.
pub(super) fn weight(weights: Option<&[Weight]>, i: usize) -> Weight {
    weights.map_or(Weight::ONE, |w| w[i])
}

/// The robust scales of one run's residual components.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct Scales {
    pub(super) position_m: f64,
    pub(super) heading_rad: Option<f64>,
    /// The heading row's channel weight before any robust weight of its own.
    pub(super) heading_channel: f64,
}

/// Cauchy weight of a mean squared residual component `u2` (in units of its scales).
fn cauchy_weight(u2: f64) -> f64 {
    1.0 / (1.0 + u2 / (CAUCHY_C * CAUCHY_C))
}

impl Problem<'_, '_> {
    /// The weights of `run` from its squared residuals `d2` and the channel variances `s2`,
    /// with the channel weights `channel` (a priori 1): one Cauchy weight from all its
    /// components, or with [`ExactOptions::heading_apart`](super::ExactOptions::heading_apart)
    /// the position's from x and y and the heading row's from the heading alone.
    fn cauchy(
        &self,
        run: &RunObservation<'_>,
        d2: &[f64; CHANNELS],
        s2: &[f64; CHANNELS],
        mut channel: [f64; CHANNELS],
    ) -> Weight {
        let z = |c: usize| d2[c] / s2[c];
        if self.options.heading_apart && self.heading(run).is_some() {
            let position = cauchy_weight(0.5 * (z(X) + z(Y)));
            channel[HEADING] *= cauchy_weight(z(HEADING)) / position;
            return Weight {
                run: position,
                channel,
            };
        }
        let u2 = (0..CHANNELS).map(z).sum::<f64>() / self.components(run) as f64;
        Weight {
            run: cauchy_weight(u2),
            channel,
        }
    }

    /// Whether runs `a` and `b` are peers (see the `exact` module docs).
    pub(super) fn peers(a: &RunObservation<'_>, b: &RunObservation<'_>) -> bool {
        let (la, lb) = (a.characteristic_length_m(), b.characteristic_length_m());
        core::mem::discriminant(&a.path) == core::mem::discriminant(&b.path)
            && Self::is_path(a) == Self::is_path(b)
            && fmax(la, lb) <= PEER_LENGTH_RATIO * fmin(la, lb)
    }

    /// Robust weights and scales of the runs at `p` (weights into `weights`, scales into
    /// `scales`, both indexed like `runs`; at most [`MAX_WEIGHTED_RUNS`] runs). Returns whether
    /// every weight stayed within its tolerance of the weight it replaced ([`WEIGHT_TOLERANCE`]
    /// for run weights, [`CHANNEL_TOLERANCE`] relative for channel weights).
    /// With `frozen`, the scales and channel weights are kept and only the run weights are
    /// recomputed. `known` are residual rows already computed at `p`.
    pub(super) fn reweight(
        &self,
        p: &[f64; 3],
        known: Option<&Residuals>,
        weights: &mut [Weight; MAX_WEIGHTED_RUNS],
        scales: &mut [Option<Scales>; MAX_WEIGHTED_RUNS],
        frozen: bool,
    ) -> bool {
        let mut stable = true;
        let model = ArcModel::from_geometry(&self.geometry(p));
        let runs = &self.runs[..self.runs.len().min(MAX_WEIGHTED_RUNS)];
        // A grouped run's residual rows are taken about its group's offset (with the weights
        // the parameters were fitted with).
        let offsets = self.offsets(Some(&weights[..runs.len()]), known, &model);
        // Squared x, y and (ℓ-scaled) heading residuals of every run.
        let mut d2 = [[0.0; CHANNELS]; MAX_WEIGHTED_RUNS];
        let mut m = 0;
        for (i, run) in runs.iter().enumerate() {
            if Self::usable(run) {
                d2[i] = match (self.group(run), Self::kept(i, run, known)) {
                    (Some(g), _) => {
                        let mut r = self.end_rows(i, run, known, &model);
                        r[X] -= offsets[g][0];
                        r[Y] -= offsets[g][1];
                        squares(&r)
                    }
                    (None, Some(k)) => squares(&k.rows),
                    (None, None) => self.distance2(run, &model),
                };
                m += self.components(run);
            }
        }
        let fitted = self.n + 2 * self.groups.count();
        let dof = if m > fitted {
            m as f64 / (m - fitted) as f64
        } else {
            1.0
        };
        let mut buf = [0.0; MAX_WEIGHTED_RUNS];
        // σ² of one component of `channels` (summed, all of one kind) from the squared
        // residuals of `run`'s peers, not below the measurement's rounding, and the number of
        // peers it came from; `None` with fewer than `MIN_PEERS` peers.
        let mut scale2 = |run: &RunObservation<'_>, channels: &[usize]| -> Option<(f64, usize)> {
            let heading = channels.contains(&HEADING);
            let k = channels.len();
            let mut count = 0;
            for (j, other) in runs.iter().enumerate() {
                let has = !heading || self.heading(other).is_some();
                if Self::usable(other) && has && Self::peers(run, other) {
                    buf[count] = channels.iter().map(|&c| d2[j][c]).sum::<f64>() / chi2_median(k);
                    count += 1;
                }
            }
            let floor = if heading {
                self.options.resolution_rad * self.heading_length(run)
            } else {
                self.options.resolution_m
            };
            (count >= MIN_PEERS).then(|| {
                let s2 = median(&mut buf[..count]) * dof;
                (fmax(s2, floor * floor / 12.0), count)
            })
        };
        for (i, run) in runs.iter().enumerate() {
            let old = weights[i];
            if frozen {
                // The channel variances the held weights and scales were made from.
                let (Some(held), true) = (scales[i], Self::usable(run)) else {
                    continue;
                };
                let sp2 = held.position_m * held.position_m;
                let mut s2 = [sp2; CHANNELS];
                s2[X] = sp2 / old.channel[X];
                s2[Y] = sp2 / old.channel[Y];
                if let Some(h) = held.heading_rad {
                    let sh = h * self.heading_length(run);
                    s2[HEADING] = sh * sh;
                }
                let mut channel = old.channel;
                channel[HEADING] = held.heading_channel;
                let new = self.cauchy(run, &d2[i], &s2, channel);
                stable &= libm::fabs(new.run - old.run) <= WEIGHT_TOLERANCE
                    && (!self.options.heading_apart
                        || libm::fabs(new.row(HEADING) - old.row(HEADING)) <= WEIGHT_TOLERANCE);
                weights[i] = new;
                continue;
            }
            weights[i] = Weight::ONE;
            scales[i] = None;
            if !Self::usable(run) {
                continue;
            }
            let Some((sp2, peers)) = scale2(run, &[X, Y]) else {
                continue;
            };
            // Channel scales: x and y apart for an end pose with enough peers (a path's knots
            // share no axes), the heading whenever it is used.
            let mut s2 = [sp2; CHANNELS];
            let channels =
                self.options.channel_weights && !Self::is_path(run) && peers >= MIN_CHANNEL_PEERS;
            if channels {
                let (Some((sx2, _)), Some((sy2, _))) = (scale2(run, &[X]), scale2(run, &[Y]))
                else {
                    continue;
                };
                s2[X] = sx2;
                s2[Y] = sy2;
            }
            let mut sh2 = None;
            let mut heading_peers = 0;
            if self.heading(run).is_some() {
                let Some((s, count)) = scale2(run, &[HEADING]) else {
                    continue;
                };
                s2[HEADING] = s;
                sh2 = Some(s);
                heading_peers = count;
            }
            // Each channel weighted by the pooled position variance over its own, so that the
            // fit stays in metres of position across runs of different kinds.
            let mut channel = [1.0; CHANNELS];
            if channels {
                channel[X] = sp2 / s2[X];
                channel[Y] = sp2 / s2[Y];
                if heading_peers >= MIN_CHANNEL_PEERS {
                    channel[HEADING] = sp2 / s2[HEADING];
                }
            }
            let new = self.cauchy(run, &d2[i], &s2, channel);
            stable &= libm::fabs(new.run - old.run) <= WEIGHT_TOLERANCE
                && (0..CHANNELS).all(|c| {
                    let (a, b) = (old.channel[c], new.channel[c]);
                    libm::fabs(a - b) <= CHANNEL_TOLERANCE * fmax(a, b)
                });
            weights[i] = new;
            scales[i] = Some(Scales {
                position_m: libm::sqrt(sp2),
                heading_rad: sh2.map(|s| libm::sqrt(s) / self.heading_length(run)),
                heading_channel: channel[HEADING],
            });
        }
        stable
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    /// The insertion sort gives std's order: the sorted slice and the median are bit for bit
    /// those of `sort_unstable_by(f64::total_cmp)`, for every length up to the most runs, with
    /// repeated values, signed zeros and infinities among the values.
    #[test]
    fn median_matches_std_sort() {
        let mut state = 0x2545_f491_4f6c_dd1d_u64;
        for n in 1..=MAX_WEIGHTED_RUNS {
            for _ in 0..4 {
                let mut v: Vec<f64> = (0..n)
                    .map(|_| {
                        state ^= state << 13;
                        state ^= state >> 7;
                        state ^= state << 17;
                        match state % 16 {
                            0 => 0.0,
                            1 => -0.0,
                            2 => f64::INFINITY,
                            3 => 1.5,
                            _ => (state >> 11) as f64 * 1e-12 - 4.0e3,
                        }
                    })
                    .collect();
                let mut reference = v.clone();
                reference.sort_unstable_by(f64::total_cmp);
                let m = median(&mut v);
                let bits = |s: &[f64]| s.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
                assert_eq!(bits(&v), bits(&reference), "n = {n}");
                let expected = if n % 2 == 1 {
                    reference[n / 2]
                } else {
                    0.5 * (reference[n / 2 - 1] + reference[n / 2])
                };
                assert_eq!(m.to_bits(), expected.to_bits(), "n = {n}");
            }
        }
    }
}
