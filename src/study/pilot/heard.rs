//! What the pilot hears of its autopilot: each position (a [`Fix`]), its modes, COLLISION
//! messages, STATUSTEXTs, version and parameters ([`Heard`], kept by the reader thread), and
//! the row's clock carried on from another vehicle's last position ([`RowClock`]).

use std::time::Instant;

use glam::DVec3;
use mavlink::dialects::ardupilotmega::{MavMessage, MavModeFlag};

/// One position of the vehicle, as the pilot heard it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Fix {
    /// The vehicle's clock, ms.
    pub time_boot_ms: u32,
    /// Scene ENU, metres.
    pub enu_m: DVec3,
    /// Velocity, scene ENU m/s.
    pub velocity_enu_mps: DVec3,
    /// Heading, degrees clockwise from north (`None` when the autopilot does not know it).
    pub heading_deg: Option<f64>,
    /// The row's clock at this position, seconds: the vehicle's own from its boot, or the
    /// row's first vehicle's ([`RowClock`]).
    pub row_s: f64,
}

/// Another vehicle's clock as a pilot hears it: the clock the second and further vehicles of
/// a row time their `until` legs by (its last position's time carried on at its speedup).
#[derive(Debug, Clone)]
pub struct RowClock {
    /// What the first vehicle's pilot heard.
    pub reference: std::sync::Arc<std::sync::Mutex<Heard>>,
    /// Its speedup (asked of its SITL).
    pub speedup: f64,
}

impl RowClock {
    /// The first vehicle's clock now, seconds from its boot; `None` before its first position.
    pub fn now_s(&self) -> Option<f64> {
        let heard = self.reference.lock().ok()?;
        let at = heard.position_at?;
        let now = Instant::now();
        Some(carried(heard.time_boot_ms, at, now, self.speedup))
    }
}

/// What the autopilot said, and its positions sampled.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Heard {
    /// Its positions in the scene's frame (ENU, m) with its clock (ms), one each
    /// [`TRACK_PERIOD_MS`] of its clock: the first [`TRACK_POINTS_KEPT`].
    pub track: Vec<(u32, DVec3)>,
    /// Its last position, with its clock (ms).
    pub last_fix: Option<(u32, DVec3)>,
    /// Armed at its last heartbeat.
    pub armed: bool,
    /// Its mode at its last heartbeat (custom_mode).
    pub mode: Option<u32>,
    /// Every mode it entered, in order, with its clock then (ms; of the last position).
    pub modes: Vec<(u32, u32)>,
    /// COLLISION messages it sent.
    pub collision_messages: u64,
    /// Its clock (ms) at the first COLLISION message.
    pub first_collision_ms: Option<u32>,
    /// The last [`RECENT_TEXTS`] STATUSTEXTs: its clock (ms), severity, text (what an error
    /// message quotes).
    pub recent_texts: std::collections::VecDeque<(u32, u8, String)>,
    /// Its STATUSTEXTs about avoidance (avoid, ADS-B, proximity, obstacle, fence), in order,
    /// repeats of the one before left out: the first [`AVOIDANCE_TEXTS_KEPT`].
    pub avoidance_texts: Vec<String>,
    /// Avoidance STATUSTEXTs past those, counted.
    pub avoidance_texts_not_kept: u64,
    /// The last avoidance STATUSTEXT heard, kept or not (a repeat of it is left out).
    last_avoidance_text: String,
    /// AUTOPILOT_VERSION: `major.minor.patch (git hash)`.
    pub version: Option<String>,
    /// Its clock at the last position, ms.
    pub time_boot_ms: u32,
    /// When the last position came (wall clock).
    pub position_at: Option<Instant>,
    /// Its clock (ms) in its last message that carries it (a position, with or without a
    /// fix, or an attitude), and when that came (wall clock).
    pub clock: Option<(u32, Instant)>,
    /// PARAM_VALUE: the last value and type heard of each parameter, by name (one entry a
    /// name: as many as the autopilot has parameters).
    pub params: std::collections::HashMap<String, (f32, u8)>,
}

/// The vehicle's clock between two points of [`Heard::track`], ms.
pub const TRACK_PERIOD_MS: u32 = 500;

/// The most points [`Heard::track`] keeps (two hours at [`TRACK_PERIOD_MS`]).
pub const TRACK_POINTS_KEPT: usize = 14_400;

/// How many of the last STATUSTEXTs [`Heard`] keeps.
pub const RECENT_TEXTS: usize = 20;

/// How many avoidance STATUSTEXTs [`Heard`] keeps (the rest are counted).
pub const AVOIDANCE_TEXTS_KEPT: usize = 100;

/// Whether a STATUSTEXT is about avoidance: avoid, ADS-B, proximity, obstacle or fence.
fn about_avoidance(text: &str) -> bool {
    let t = text.to_ascii_lowercase();
    ["avoid", "adsb", "proximity", "obstacle", "fence"]
        .iter()
        .any(|w| t.contains(w))
}

/// What the reader thread passes on.
pub enum News {
    /// A position.
    Fix(Fix),
    /// Anything else that changed [`Heard`].
    Other,
    /// In lockstep: a second of the row's clock passed (at its milliseconds), for a pilot
    /// that has heard no position yet to ask again on the row's clock, not the wall's.
    Tick(u32),
}

impl Heard {
    /// Its last five STATUSTEXTs, newest first, joined with "; " (what an error quotes).
    pub fn last_texts(&self) -> String {
        let texts: Vec<&str> = self
            .recent_texts
            .iter()
            .rev()
            .take(5)
            .map(|t| t.2.as_str())
            .collect();
        texts.join("; ")
    }

    /// Take a position at `ms` of the vehicle's clock: the last, and into the track when
    /// [`TRACK_PERIOD_MS`] have passed since its last point.
    pub fn take_position(&mut self, ms: u32, enu_m: DVec3) {
        self.last_fix = Some((ms, enu_m));
        let due = self
            .track
            .last()
            .is_none_or(|(t, _)| ms >= t.saturating_add(TRACK_PERIOD_MS));
        if due && self.track.len() < TRACK_POINTS_KEPT {
            self.track.push((ms, enu_m));
        }
    }

    /// The track and the last position as waypoints in the text an intruder's track is
    /// given in (`t_s e_m n_m u_m; ...`, seconds of the vehicle's clock, decimetres); `None`
    /// when no position was heard.
    ///
    /// ```
    /// use glam::DVec3;
    /// let mut heard = savsim::study::pilot::heard::Heard::default();
    /// assert_eq!(heard.track_text(), None);
    /// for (ms, e) in [(1000, 0.0), (1200, 1.0), (1500, 2.5), (1700, 3.0)] {
    ///     heard.take_position(ms, DVec3::new(e, 10.0, 20.0));
    /// }
    /// assert_eq!(heard.track_text().unwrap(), "1.000 0.0 10.0 20.0; 1.500 2.5 10.0 20.0; 1.700 3.0 10.0 20.0");
    /// ```
    pub fn track_text(&self) -> Option<String> {
        self.track_text_shifted(0.0)
    }

    /// [`Heard::track_text`] with `offset_s` added to every time (onto the row's clock).
    pub fn track_text_shifted(&self, offset_s: f64) -> Option<String> {
        let last = self.last_fix?;
        let mut points = self.track.clone();
        if points.last().is_none_or(|(t, _)| *t < last.0) {
            points.push(last);
        }
        let one = |(ms, p): &(u32, DVec3)| {
            format!(
                "{:.3} {:.1} {:.1} {:.1}",
                f64::from(*ms) / 1000.0 + offset_s,
                p.x,
                p.y,
                p.z
            )
        };
        Some(points.iter().map(one).collect::<Vec<_>>().join("; "))
    }
}

/// Take one message other than a position into `heard`.
pub(crate) fn hear(heard: &mut Heard, from_autopilot: bool, message: MavMessage) {
    let now = heard.time_boot_ms;
    match message {
        MavMessage::HEARTBEAT(hb) if from_autopilot => {
            heard.armed = hb
                .base_mode
                .contains(MavModeFlag::MAV_MODE_FLAG_SAFETY_ARMED);
            if heard.mode != Some(hb.custom_mode) {
                heard.mode = Some(hb.custom_mode);
                heard.modes.push((now, hb.custom_mode));
            }
        }
        MavMessage::COLLISION(_) => {
            heard.collision_messages += 1;
            heard.first_collision_ms.get_or_insert(now);
        }
        MavMessage::STATUSTEXT(t) => {
            let text = t
                .text
                .to_str()
                .unwrap_or("?")
                .trim_end_matches('\0')
                .to_owned();
            if about_avoidance(&text) && heard.last_avoidance_text != text {
                if heard.avoidance_texts.len() < AVOIDANCE_TEXTS_KEPT {
                    heard.avoidance_texts.push(text.clone());
                } else {
                    heard.avoidance_texts_not_kept += 1;
                }
                heard.last_avoidance_text.clone_from(&text);
            }
            if heard.recent_texts.len() == RECENT_TEXTS {
                heard.recent_texts.pop_front();
            }
            heard.recent_texts.push_back((now, t.severity as u8, text));
        }
        MavMessage::PARAM_VALUE(v) => {
            let name = v.param_id.to_str().unwrap_or("").trim_end_matches('\0');
            heard
                .params
                .insert(name.to_owned(), (v.param_value, v.param_type as u8));
        }
        MavMessage::AUTOPILOT_VERSION(v) => {
            let s = v.flight_sw_version;
            let hash: String = v
                .flight_custom_version
                .iter()
                .take_while(|b| **b != 0)
                .map(|b| char::from(*b))
                .collect();
            heard.version = Some(format!(
                "{}.{}.{} ({hash})",
                s >> 24,
                (s >> 16) & 0xff,
                (s >> 8) & 0xff
            ));
        }
        _ => {}
    }
}

/// A clock's `ms` heard at `at`, carried on to `now` at `speedup`, seconds.
pub(crate) fn carried(ms: u32, at: Instant, now: Instant, speedup: f64) -> f64 {
    f64::from(ms) / 1000.0 + now.saturating_duration_since(at).as_secs_f64() * speedup
}

#[cfg(test)]
mod tests {
    use super::*;
    use mavlink::dialects::ardupilotmega::{MavSeverity, STATUSTEXT_DATA};

    fn text(t: &str) -> MavMessage {
        let mut data = STATUSTEXT_DATA {
            severity: MavSeverity::MAV_SEVERITY_INFO,
            ..STATUSTEXT_DATA::default()
        };
        data.text = t.into();
        MavMessage::STATUSTEXT(data)
    }

    /// What the pilot keeps of an autopilot that talks without end: the last texts for error
    /// messages, the first avoidance texts and a count of the rest; nothing grows with time.
    #[test]
    fn texts_heard_for_ever_are_kept_bounded_and_the_rest_counted() {
        let mut heard = Heard::default();
        for k in 0..5000 {
            heard.time_boot_ms = k;
            hear(&mut heard, true, text(&format!("ADSB: avoiding {k}")));
            hear(&mut heard, true, text("ADSB: avoiding the same"));
            hear(&mut heard, true, text("ADSB: avoiding the same"));
            hear(&mut heard, true, text(&format!("battery {k}")));
        }
        assert_eq!(heard.avoidance_texts.len(), AVOIDANCE_TEXTS_KEPT);
        assert_eq!(heard.avoidance_texts[0], "ADSB: avoiding 0");
        assert_eq!(heard.avoidance_texts[1], "ADSB: avoiding the same");
        // Each round adds two avoidance texts (the repeat of the same one is left out).
        assert_eq!(
            heard.avoidance_texts_not_kept,
            2 * 5000 - AVOIDANCE_TEXTS_KEPT as u64
        );
        assert_eq!(heard.recent_texts.len(), RECENT_TEXTS);
        assert_eq!(heard.recent_texts.back().unwrap().2, "battery 4999");
    }
}
