//! The event rules' constants, with the reference table's defaults.

use serde::{Deserialize, Serialize};

/// The event rules' constants (see the module's documentation). The defaults are for the
/// reference table (SPEC section 1) at 100 to 230 frames per second.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct EventConfig {
    /// The field's length (goal line to goal line, along `x`), mm; the table frame's origin
    /// is its centre. Default 1200 (SPEC section 1).
    pub field_length_mm: f64,
    /// The field's width (wall to wall, along `y`), mm. Default 680.
    pub field_width_mm: f64,
    /// The rods' axes' height above the field, mm (to place each rod's axis in the table
    /// frame from its calibrated image path). Default 80.
    pub rod_axis_height_mm: f64,
    /// The goal mouth's width across the table (along `y`), centred on the field's centre
    /// line, mm. Default 205 (common table football tables: 200 to 210 mm).
    pub goal_width_mm: f64,
    /// How long the ball must stay away after crossing a goal line for a goal, s.
    pub goal_grace_s: f64,
    /// A goal line crossed by the prediction alone (the ball unseen at the crossing) counts
    /// only when the ball was last seen at most this long before the crossing row, s. A ball
    /// entering a goal mouth stays in view until its centre reaches the line (the end wall
    /// hides only what has passed it), so it is lost a frame before it crosses, or a few
    /// when a figure's foot hides it there too; a ball lost longer before (a hand holding
    /// it, a figure hiding it on the field) may not have gone in. Default 0.025 (5 frames at
    /// 200 per second, 2 at 100).
    pub goal_unseen_max_s: f64,
    /// An `ok` row within this distance of a goal line, on the field side, during the grace
    /// time, is the ball coming back out of the goal: no goal, mm.
    pub return_zone_mm: f64,
    /// How far inside the field the ball's centre must be to count as on the field (for the
    /// return and for arming the next goal), mm.
    pub line_margin_mm: f64,
    /// A shot's least speed, mm/s.
    pub shot_min_speed_mm_s: f64,
    /// A shot's least speed increase over the window before it, mm/s.
    pub shot_min_jump_mm_s: f64,
    /// The window before a row that gives its speed before a kick: from this age, s...
    pub shot_before_min_s: f64,
    /// ... to this age, s.
    pub shot_before_max_s: f64,
    /// The `ok` rows after the jump's within this time give the shot's speed (their mean), s.
    pub shot_settle_s: f64,
    /// `ok` rows within the settle time (the jump's included) that must be faster than the
    /// speed before by the least jump: one row alone may be a bad detection (a ball cut by
    /// a wall or a figure restarts the filter's velocity from a displaced position).
    pub shot_min_rows: u32,
    /// No second shot within this time of one, s.
    pub shot_refractory_s: f64,
    /// A rod not seen swinging is credited with a shot when its axis is the nearest to the
    /// ball and within this distance (along `x`), mm.
    pub rod_reach_mm: f64,
    /// A rod seen swinging at the kick is credited with it when its axis is within this
    /// distance of the ball (along `x`), mm: a figure's foot swung forward to its full
    /// stretch (a toe about the axes' height below the axis, 0.8 rad forward: 56 mm) plus
    /// the ball's radius. Default 85.
    pub rod_swing_reach_mm: f64,
    /// A ball seen this far beyond the field's edge (outside a goal mouth) is out, mm.
    pub out_margin_mm: f64,
    /// A ball last seen within this distance of the field's edge ...
    pub out_edge_mm: f64,
    /// ... and not seen again for this long is out, s.
    pub out_lost_s: f64,
    /// The ball's speed for the stop is fitted over the `ok` rows younger than this, s (the
    /// positions' noise is measured over the same rows).
    pub stopped_window_s: f64,
    /// The ball is still when its fitted speed is within this many of the speed's standard
    /// errors of zero (from the measured noise); it moves again beyond three times that.
    pub stopped_sigmas: f64,
    /// Still for this long (the windows' times) has stopped, s.
    pub stopped_min_s: f64,
}

impl Default for EventConfig {
    fn default() -> Self {
        EventConfig {
            field_length_mm: 1200.0,
            field_width_mm: 680.0,
            rod_axis_height_mm: 80.0,
            goal_width_mm: 205.0,
            goal_grace_s: 0.5,
            goal_unseen_max_s: 0.025,
            return_zone_mm: 200.0,
            line_margin_mm: 10.0,
            shot_min_speed_mm_s: 1500.0,
            shot_min_jump_mm_s: 1000.0,
            shot_before_min_s: 0.015,
            shot_before_max_s: 0.06,
            shot_settle_s: 0.025,
            shot_min_rows: 2,
            shot_refractory_s: 0.2,
            rod_reach_mm: 60.0,
            rod_swing_reach_mm: 85.0,
            out_margin_mm: 35.0,
            out_edge_mm: 60.0,
            out_lost_s: 1.0,
            stopped_window_s: 0.06,
            stopped_sigmas: 3.0,
            stopped_min_s: 0.5,
        }
    }
}

impl EventConfig {
    /// Checks that every number is finite and positive (the margins may be 0), and the shot
    /// window is ordered.
    pub fn validate(&self) -> Result<(), crate::CoreError> {
        let fields = [
            ("field_length_mm", self.field_length_mm, false),
            ("field_width_mm", self.field_width_mm, false),
            ("rod_axis_height_mm", self.rod_axis_height_mm, true),
            ("goal_width_mm", self.goal_width_mm, false),
            ("goal_grace_s", self.goal_grace_s, false),
            ("goal_unseen_max_s", self.goal_unseen_max_s, true),
            ("return_zone_mm", self.return_zone_mm, false),
            ("line_margin_mm", self.line_margin_mm, true),
            ("shot_min_speed_mm_s", self.shot_min_speed_mm_s, false),
            ("shot_min_jump_mm_s", self.shot_min_jump_mm_s, false),
            ("shot_before_min_s", self.shot_before_min_s, true),
            ("shot_before_max_s", self.shot_before_max_s, false),
            ("shot_settle_s", self.shot_settle_s, true),
            ("shot_refractory_s", self.shot_refractory_s, true),
            ("rod_reach_mm", self.rod_reach_mm, true),
            ("rod_swing_reach_mm", self.rod_swing_reach_mm, true),
            ("out_margin_mm", self.out_margin_mm, true),
            ("out_edge_mm", self.out_edge_mm, true),
            ("out_lost_s", self.out_lost_s, false),
            ("stopped_window_s", self.stopped_window_s, false),
            ("stopped_sigmas", self.stopped_sigmas, false),
            ("stopped_min_s", self.stopped_min_s, false),
        ];
        for (field, v, zero_ok) in fields {
            if !v.is_finite() || v < 0.0 || (v == 0.0 && !zero_ok) {
                return Err(crate::CoreError::Events {
                    field,
                    reason: format!(
                        "must be a finite {} number, got {v}",
                        if zero_ok { "non-negative" } else { "positive" }
                    ),
                });
            }
        }
        if self.goal_width_mm >= self.field_width_mm {
            return Err(crate::CoreError::Events {
                field: "goal_width_mm",
                reason: format!(
                    "must be below the field's width ({} >= {})",
                    self.goal_width_mm, self.field_width_mm
                ),
            });
        }
        if self.shot_before_min_s >= self.shot_before_max_s {
            return Err(crate::CoreError::Events {
                field: "shot_before_min_s",
                reason: format!(
                    "must be below shot_before_max_s ({} >= {})",
                    self.shot_before_min_s, self.shot_before_max_s
                ),
            });
        }
        Ok(())
    }
}
