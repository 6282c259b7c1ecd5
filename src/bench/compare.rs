//! Matching a mode's collisions to the reference's.

use std::collections::BTreeMap;

use crate::collision::events::{Event, EventKind};

/// The collisions among `events`: (obstacle, time of impact), in order.
pub fn collisions(events: &[Event]) -> Vec<(&str, f64)> {
    events
        .iter()
        .filter_map(|e| match &e.kind {
            EventKind::Collision {
                obstacle,
                time_of_impact,
                ..
            } => Some((obstacle.as_str(), *time_of_impact)),
            _ => None,
        })
        .collect()
}

/// Matches `found` to `truth` by obstacle, k-th to k-th: (missed, false, |dt| of each match,
/// |dt| of the first contact when both have one).
pub fn compare(
    truth: &[(&str, f64)],
    found: &[(&str, f64)],
) -> (usize, usize, Vec<f64>, Option<f64>) {
    let mut by_obstacle: BTreeMap<&str, (Vec<f64>, Vec<f64>)> = BTreeMap::new();
    for &(o, t) in truth {
        by_obstacle.entry(o).or_default().0.push(t);
    }
    for &(o, t) in found {
        by_obstacle.entry(o).or_default().1.push(t);
    }
    let (mut missed, mut false_, mut errors) = (0, 0, Vec::new());
    for (t, f) in by_obstacle.values() {
        missed += t.len().saturating_sub(f.len());
        false_ += f.len().saturating_sub(t.len());
        errors.extend(t.iter().zip(f).map(|(a, b)| (a - b).abs()));
    }
    let first = match (truth.first(), found.first()) {
        (Some(a), Some(b)) => Some((a.1 - b.1).abs()),
        _ => None,
    };
    (missed, false_, errors, first)
}

#[cfg(test)]
mod tests {
    use super::compare;

    #[test]
    fn compare_matches_by_obstacle_in_order() {
        let truth = [("a", 1.0), ("b", 2.0), ("a", 5.0)];
        let found = [("a", 1.2), ("c", 3.0)];
        let (missed, false_, errors, first) = compare(&truth, &found);
        assert_eq!((missed, false_), (2, 1));
        assert_eq!(errors.len(), 1);
        assert!((errors[0] - 0.2).abs() < 1e-12);
        assert!((first.unwrap() - 0.2).abs() < 1e-12);
    }
}
