//! MIT Lincoln Laboratory's statistical encounter models (em-model-manned-bayes, BSD-2):
//! their ASCII files read, their Bayesian networks sampled, and each sample flown into a
//! track with turns, climbs and speed changes.
//!
//! A model file has an initial network (`labels_initial`, `G_initial` (parents by rows),
//! `r_initial` (bins per variable), `N_initial` (counts, variable by variable, each an
//! `r x q` matrix column by column, `q` the product of its parents' bins with the parent of
//! lowest index varying fastest)), a transition network over the same variables and the next
//! second's dynamic ones (`labels_transition`, `G_transition`, `r_transition`,
//! `N_transition`), the bins' `boundaries` (`*` for a categorical variable) and the
//! `resample_rates`. The uncorrelated models' variables are the geographic domain `G`, the
//! airspace class `A`, the altitude layer `L` (ft), the airspeed `v` (knots), the acceleration
//! `\dot v` (knots/s), the vertical rate `\dot h` (ft/min) and the turn rate `\dot \psi`
//! (deg/s).
//!
//! Sampling: ancestral, in an order where parents come first, each variable's bin drawn from
//! its counts given its parents' bins (a column with no counts: every bin alike). A bin
//! becomes a value uniformly within its boundaries (0 for a dynamic variable's bin that
//! straddles zero); each second the dynamic variables' bins are drawn from the transition
//! network, and a value is drawn again when its bin changes, or else with the variable's
//! resample rate.

use rand::Rng;

/// One Bayesian network: variables, parents, bins and counts.
#[derive(Debug, Clone, PartialEq)]
pub struct Network {
    /// Each variable's label.
    pub labels: Vec<String>,
    /// Each variable's parents (ascending).
    pub parents: Vec<Vec<usize>>,
    /// Each variable's bins.
    pub bins: Vec<usize>,
    /// Each variable's counts, `bins x configurations`, column by column (only the
    /// variables this network samples).
    pub counts: Vec<Vec<f64>>,
    /// A sampling order, parents first (only the variables this network samples).
    pub order: Vec<usize>,
}

/// A model: its two networks, how the dynamic variables map from one second to the next,
/// and how bins become values.
#[derive(Debug, Clone, PartialEq)]
pub struct Model {
    /// The initial network.
    pub initial: Network,
    /// The transition network (its first variables the initial ones).
    pub transition: Network,
    /// (variable at t, variable at t+1) in the transition network.
    pub temporal: Vec<(usize, usize)>,
    /// Each initial variable's bin boundaries (`None`: categorical).
    pub boundaries: Vec<Option<Vec<f64>>>,
    /// Each initial variable's resample rate, per second.
    pub resample_rates: Vec<f64>,
}

/// Why a model file could not be read.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ModelError {
    /// A section is missing.
    #[error("no `# {0}` section")]
    Missing(&'static str),
    /// A section that does not hold what it must.
    #[error("section {section}: {message}")]
    Bad {
        /// The section.
        section: &'static str,
        /// What is wrong.
        message: String,
    },
}

/// Most variables and bins a model may have (the published ones have 7 and 10, up to 8).
const MAX_VARIABLES: usize = 64;
const MAX_BINS: usize = 1024;
const MAX_CONFIGURATIONS: usize = 1 << 24;

fn bad(section: &'static str, message: impl Into<String>) -> ModelError {
    ModelError::Bad {
        section,
        message: message.into(),
    }
}

/// The lines of each `# name` section.
fn sections(text: &str) -> Vec<(&str, Vec<&str>)> {
    let mut out: Vec<(&str, Vec<&str>)> = Vec::new();
    for line in text.lines() {
        let line = line.trim();
        if let Some(name) = line.strip_prefix('#') {
            out.push((name.trim(), Vec::new()));
        } else if let Some((_, lines)) = out.last_mut() {
            if !line.is_empty() {
                lines.push(line);
            }
        }
    }
    out
}

/// The lines of section `name`.
fn section<'a>(
    all: &'a [(&str, Vec<&'a str>)],
    name: &'static str,
) -> Result<&'a [&'a str], ModelError> {
    all.iter()
        .find(|(n, _)| *n == name)
        .map(|(_, l)| l.as_slice())
        .ok_or(ModelError::Missing(name))
}

fn numbers(section: &'static str, line: &str) -> Result<Vec<f64>, ModelError> {
    line.split_whitespace()
        .map(|x| {
            x.parse::<f64>()
                .ok()
                .filter(|v| v.is_finite())
                .ok_or_else(|| bad(section, format!("not a number: {x:?}")))
        })
        .collect()
}

impl Model {
    /// Read a model file.
    pub fn parse(text: &str) -> Result<Self, ModelError> {
        let all = sections(text);
        let get = |name: &'static str| section(&all, name);
        let labels = |name: &'static str| -> Result<Vec<String>, ModelError> {
            let line = get(name)?.first().ok_or_else(|| bad(name, "empty"))?;
            let labels: Vec<String> = line
                .split(',')
                .map(|l| l.trim().trim_matches('"').to_string())
                .collect();
            if labels.is_empty() || labels.len() > MAX_VARIABLES {
                return Err(bad(name, format!("{} variables", labels.len())));
            }
            Ok(labels)
        };
        let initial_labels = labels("labels_initial")?;
        let transition_labels = labels("labels_transition")?;
        let n0 = initial_labels.len();
        let initial = network(
            &all,
            initial_labels,
            ["G_initial", "r_initial", "N_initial"],
            0,
        )?;
        let transition = network(
            &all,
            transition_labels,
            ["G_transition", "r_transition", "N_transition"],
            n0,
        )?;
        if transition.labels.len() <= n0 || transition.bins[..n0] != initial.bins[..] {
            return Err(bad(
                "r_transition",
                "the transition network must begin with the initial variables",
            ));
        }
        let temporal = temporal_map(&transition.labels)?;
        let same_bins = |now: usize, next: usize| transition.bins[now] == transition.bins[next];
        if temporal
            .iter()
            .any(|&(now, next)| now >= n0 || next < n0 || !same_bins(now, next))
        {
            return Err(bad(
                "labels_transition",
                "a (t) variable must be an initial one, its (t+1) a transition one with as many bins",
            ));
        }
        let boundaries = get("boundaries")?;
        if boundaries.len() < n0 {
            return Err(bad(
                "boundaries",
                format!("{} lines for {n0} variables", boundaries.len()),
            ));
        }
        let boundaries = boundaries[..n0]
            .iter()
            .enumerate()
            .map(|(i, line)| {
                if line.trim() == "*" {
                    return Ok(None);
                }
                let b = numbers("boundaries", line)?;
                let sorted = b.windows(2).all(|w| w[0] < w[1]);
                if b.len() != initial.bins[i] + 1 || !sorted {
                    return Err(bad(
                        "boundaries",
                        format!(
                            "variable {}: {} increasing boundaries for {} bins",
                            i + 1,
                            b.len(),
                            initial.bins[i]
                        ),
                    ));
                }
                Ok(Some(b))
            })
            .collect::<Result<Vec<_>, _>>()?;
        let rates = get("resample_rates")?
            .first()
            .map(|l| numbers("resample_rates", l))
            .transpose()?
            .unwrap_or_default();
        if rates.len() != n0 || rates.iter().any(|r| !(0.0..=1.0).contains(r)) {
            return Err(bad(
                "resample_rates",
                "one probability per initial variable",
            ));
        }
        Ok(Model {
            initial,
            transition,
            temporal,
            boundaries,
            resample_rates: rates,
        })
    }

    /// The index of the initial variable labelled `label`.
    pub fn variable(&self, label: &str) -> Option<usize> {
        self.initial.labels.iter().position(|l| l == label)
    }

    /// One sample of the initial network: a bin (from 0) per variable.
    pub fn sample_initial(&self, rng: &mut impl Rng) -> Vec<usize> {
        let mut x = vec![0; self.initial.labels.len()];
        for &i in &self.initial.order {
            x[i] = self.initial.draw(i, &x, rng);
        }
        x
    }

    /// One second on: the dynamic variables' next bins from the transition network given the
    /// current ones (`x`, a bin per initial variable, updated in place).
    pub fn step(&self, x: &mut [usize], rng: &mut impl Rng) {
        let mut state = x.to_vec();
        state.resize(self.transition.labels.len(), 0);
        for &i in &self.transition.order {
            state[i] = self.transition.draw(i, &state, rng);
        }
        for &(now, next) in &self.temporal {
            x[now] = state[next];
        }
    }

    /// A value for initial variable `i` in bin `bin`: uniform within its boundaries (0 for a
    /// dynamic variable's bin that straddles zero), the bin itself for a categorical one.
    pub fn value(&self, i: usize, bin: usize, rng: &mut impl Rng) -> f64 {
        let Some(b) = &self.boundaries[i] else {
            return bin as f64;
        };
        let (lo, hi) = (b[bin], b[bin + 1]);
        let dynamic = self.temporal.iter().any(|&(now, _)| now == i);
        if dynamic && lo < 0.0 && hi > 0.0 {
            return 0.0;
        }
        rng.random_range(lo..hi)
    }
}

/// The (t) and (t+1) variables of a transition network's labels.
fn temporal_map(labels: &[String]) -> Result<Vec<(usize, usize)>, ModelError> {
    let mut map = Vec::new();
    for (now, label) in labels.iter().enumerate() {
        if let Some(stem) = label.strip_suffix("(t)") {
            let next = labels
                .iter()
                .position(|l| l.strip_suffix("(t+1)") == Some(stem))
                .ok_or_else(|| bad("labels_transition", format!("{label} has no (t+1)")))?;
            map.push((now, next));
        }
    }
    if map.is_empty() {
        return Err(bad("labels_transition", "no (t) / (t+1) variables"));
    }
    Ok(map)
}

/// Read one network's sections; `sampled_from` is the first variable it samples (0 for the
/// initial network, the number of initial variables for the transition network).
fn network(
    all: &[(&str, Vec<&str>)],
    labels: Vec<String>,
    [g, r, n]: [&'static str; 3],
    sampled_from: usize,
) -> Result<Network, ModelError> {
    let get = |name: &'static str| section(all, name);
    let count = labels.len();
    let rows = get(g)?;
    if rows.len() != count {
        return Err(bad(g, format!("{} rows for {count} variables", rows.len())));
    }
    let matrix: Vec<Vec<f64>> = rows
        .iter()
        .map(|l| numbers(g, l))
        .collect::<Result<_, _>>()?;
    if matrix.iter().any(|row| row.len() != count) {
        return Err(bad(g, "not square"));
    }
    let parents: Vec<Vec<usize>> = (0..count)
        .map(|j| (0..count).filter(|&i| matrix[i][j] != 0.0).collect())
        .collect();
    let bins: Vec<usize> = numbers(r, get(r)?.first().ok_or_else(|| bad(r, "empty"))?)?
        .into_iter()
        .map(|b| b as usize)
        .collect();
    if bins.len() != count || bins.iter().any(|&b| b == 0 || b > MAX_BINS) {
        return Err(bad(r, format!("{count} bin counts of 1 to {MAX_BINS}")));
    }
    let flat = numbers(n, get(n)?.first().ok_or_else(|| bad(n, "empty"))?)?;
    if flat.iter().any(|&c| c < 0.0) {
        return Err(bad(n, "a negative count"));
    }
    let mut counts = Vec::new();
    let mut at = 0;
    for i in sampled_from..count {
        let q = parents[i]
            .iter()
            .try_fold(1usize, |q, &p| {
                q.checked_mul(bins[p]).filter(|&q| q <= MAX_CONFIGURATIONS)
            })
            .ok_or_else(|| bad(n, "too many parent configurations"))?;
        let size = bins[i] * q;
        let column = flat
            .get(at..at + size)
            .ok_or_else(|| bad(n, format!("{} counts: too few", flat.len())))?;
        counts.push(column.to_vec());
        at += size;
    }
    if at != flat.len() {
        return Err(bad(n, format!("{} counts: {at} expected", flat.len())));
    }
    let order = sort(&parents, sampled_from).ok_or_else(|| bad(g, "a cycle"))?;
    Ok(Network {
        labels,
        parents,
        bins,
        counts,
        order,
    })
}

/// The variables from `from` on, parents first; `None` for a cycle among them.
fn sort(parents: &[Vec<usize>], from: usize) -> Option<Vec<usize>> {
    let mut done: Vec<bool> = (0..parents.len()).map(|i| i < from).collect();
    let mut order = Vec::new();
    while order.len() < parents.len() - from {
        let next =
            (from..parents.len()).find(|&i| !done[i] && parents[i].iter().all(|&p| done[p]))?;
        done[next] = true;
        order.push(next);
    }
    Some(order)
}

impl Network {
    /// The column of variable `i`'s counts for its parents' bins in `x`.
    pub fn configuration(&self, i: usize, x: &[usize]) -> usize {
        let mut j = 0;
        let mut stride = 1;
        for &p in &self.parents[i] {
            j += x[p] * stride;
            stride *= self.bins[p];
        }
        j
    }

    /// The counts of variable `i`'s bins given its parents' bins in `x`.
    fn column(&self, i: usize, x: &[usize]) -> &[f64] {
        let r = self.bins[i];
        let j = self.configuration(i, x);
        let first_sampled = self.labels.len() - self.counts.len();
        &self.counts[i - first_sampled][j * r..(j + 1) * r]
    }

    /// The probabilities of variable `i`'s bins given its parents' bins in `x` (a column with
    /// no counts: every bin alike).
    pub fn probabilities(&self, i: usize, x: &[usize]) -> Vec<f64> {
        let column = self.column(i, x);
        let total: f64 = column.iter().sum();
        if total > 0.0 {
            column.iter().map(|c| c / total).collect()
        } else {
            vec![1.0 / column.len() as f64; column.len()]
        }
    }

    /// Draw variable `i`'s bin given its parents' bins in `x`.
    fn draw(&self, i: usize, x: &[usize], rng: &mut impl Rng) -> usize {
        let column = self.column(i, x);
        let r = column.len();
        let total: f64 = column.iter().sum();
        if total <= 0.0 {
            return rng.random_range(0..r);
        }
        let mut u = rng.random_range(0.0..total);
        for (k, c) in column.iter().enumerate() {
            if u < *c {
                return k;
            }
            u -= c;
        }
        // Rounding: the last bin with counts.
        column.iter().rposition(|&c| c > 0.0).unwrap_or(r - 1)
    }
}

/// Metres in a foot, seconds in a minute, m/s in a knot.
const FT_M: f64 = 0.3048;
const KNOT_MPS: f64 = 1852.0 / 3600.0;

/// One second of a sampled track.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TrackPoint {
    /// Seconds from the start.
    pub t_s: f64,
    /// East, north (from the start) and up (above the ground), metres.
    pub position_enu_m: glam::DVec3,
    /// Airspeed, m/s.
    pub speed_mps: f64,
}

/// A track flown from the model for `duration_s` seconds (1 s steps): starting at the origin
/// heading north at the sampled altitude and airspeed, integrating the sampled acceleration,
/// vertical rate and turn rate (an uncorrelated model's variables: `L`, `v`, `\dot v`,
/// `\dot h`, `\dot \psi`); `None` when the model lacks them or the track leaves the model's
/// speed range or goes below the ground (rejected, as the model's own tools reject them).
pub fn track(model: &Model, duration_s: usize, rng: &mut impl Rng) -> Option<Vec<TrackPoint>> {
    let var = |label: &str| model.variable(label);
    let (l, v, dv, dh, dpsi) = (
        var("L")?,
        var("v")?,
        var("\\dot v")?,
        var("\\dot h")?,
        var("\\dot \\psi")?,
    );
    let speed_range = model.boundaries[v].as_ref()?;
    let (v_min, v_max) = (
        speed_range[0] * KNOT_MPS,
        speed_range[speed_range.len() - 1] * KNOT_MPS,
    );
    let mut bins = model.sample_initial(rng);
    let mut values: Vec<f64> = (0..bins.len())
        .map(|i| model.value(i, bins[i], rng))
        .collect();
    let mut position = glam::DVec3::new(0.0, 0.0, values[l] * FT_M);
    let mut speed = values[v] * KNOT_MPS;
    let mut heading = 0.0f64;
    let mut out = Vec::with_capacity(duration_s + 1);
    for t in 0..=duration_s {
        if !(v_min..=v_max).contains(&speed) || position.z < 0.0 {
            return None;
        }
        out.push(TrackPoint {
            t_s: t as f64,
            position_enu_m: position,
            speed_mps: speed,
        });
        position += glam::DVec3::new(heading.sin(), heading.cos(), 0.0) * speed;
        position.z += values[dh] * FT_M / 60.0;
        speed += values[dv] * KNOT_MPS;
        heading += values[dpsi].to_radians();
        let before = bins.clone();
        model.step(&mut bins, rng);
        for &(i, _) in &model.temporal {
            if bins[i] != before[i] || rng.random_bool(model.resample_rates[i]) {
                values[i] = model.value(i, bins[i], rng);
            }
        }
    }
    Some(out)
}
