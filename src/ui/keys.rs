//! The preview's key bindings: one table drives dispatch, the `?` help overlay and the
//! README's key list (the parameters' keys come from `scene::params`).

use ratatui::crossterm::event::{KeyCode, KeyEvent, KeyModifiers};

pub use crate::scene::params::Param;

/// What a key does.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Action {
    SelectNext,
    SelectPrev,
    Choose(Param),
    NextParam,
    /// Adjust the active parameter: up or down, by a fine or a coarse step.
    Adjust {
        up: bool,
        coarse: bool,
    },
    /// Orbit the camera around `look_at` by degrees (yaw about `up`, pitch).
    Orbit {
        yaw: f64,
        pitch: f64,
    },
    /// Move camera and target by fractions of their distance: forward, right, up.
    Move(f64, f64, f64),
    /// Multiply the field of view.
    Zoom(f64),
    /// Turn the environment map about the up axis by degrees.
    RotateSky(f32),
    /// Multiply the environment map's intensity.
    ScaleSky(f32),
    FocusOnSelected,
    ResetAccumulation,
    Revert,
    SavePng,
    WriteScene,
    CycleCells,
    /// Next-event estimation on or off.
    ToggleNee,
    /// The denoiser off, or back on.
    ToggleDenoise,
    ToggleHelp,
    /// Esc: closes the help, else quits.
    Back,
    Quit,
}

/// A binding: the keys as the help shows them, and what they do.
pub struct Binding {
    pub keys: &'static str,
    pub help: &'static str,
}

/// The help overlay's lines, in order: [`BINDINGS`]' first, the parameters' keys from their
/// table (`scene::params`), then the rest.
pub fn help_lines() -> Vec<(String, String)> {
    let line = |b: &Binding| (b.keys.to_string(), b.help.to_string());
    let mut lines = vec![line(&BINDINGS[0])];
    lines.extend(crate::scene::params::help_lines());
    lines.extend(BINDINGS[1..].iter().map(line));
    lines
}

/// The help's lines for the keys that are not a parameter's.
pub const BINDINGS: &[Binding] = &[
    Binding {
        keys: "Tab / Shift-Tab",
        help: "select the next / previous object",
    },
    Binding {
        keys: "m",
        help: "next parameter",
    },
    Binding {
        keys: "+ / -",
        help: "raise / lower the parameter by a fine step",
    },
    Binding {
        keys: "] / [",
        help: "raise / lower it by a coarse step",
    },
    Binding {
        keys: "arrows",
        help: "orbit the camera around its target",
    },
    Binding {
        keys: "i k j l",
        help: "move forward, back, left, right",
    },
    Binding {
        keys: "u n",
        help: "move up, down",
    },
    Binding {
        keys: "z / x",
        help: "zoom in / out (field of view)",
    },
    Binding {
        keys: ", . < >",
        help: "turn the environment map 15° left, right; dim, brighten it",
    },
    Binding {
        keys: "f",
        help: "focus on the selected object",
    },
    Binding {
        keys: "r / R",
        help: "restart accumulation / revert every edit",
    },
    Binding {
        keys: "p",
        help: "save a PNG at the scene's resolution (in the background)",
    },
    Binding {
        keys: "w",
        help: "write the edited scene to NAME.edited.toml",
    },
    Binding {
        keys: "c",
        help: "cycle cells: half blocks, quadrants, sextants, ASCII",
    },
    Binding {
        keys: "e",
        help: "light sampling (next-event estimation) on / off",
    },
    Binding {
        keys: "d",
        help: "denoiser off / on (status: noise raw → denoised)",
    },
    Binding {
        keys: "?",
        help: "this help",
    },
    Binding {
        keys: "q / Esc / Ctrl-C",
        help: "quit",
    },
];

/// Degrees per orbit step, and fraction of the target distance per move step.
const ORBIT_DEG: f64 = 5.0;
const MOVE_STEP: f64 = 0.05;
const ZOOM_STEP: f64 = 0.9;
/// Degrees per turn of the environment map, and its intensity's factor per step.
const SKY_TURN_DEG: f32 = 15.0;
const SKY_SCALE: f32 = 1.25;

/// The action of a key press, if it has one.
pub fn action(key: KeyEvent) -> Option<Action> {
    use Action::*;
    if key.modifiers.contains(KeyModifiers::CONTROL) {
        return match key.code {
            KeyCode::Char('c') => Some(Quit),
            _ => None,
        };
    }
    Some(match key.code {
        KeyCode::Tab => SelectNext,
        KeyCode::BackTab => SelectPrev,
        KeyCode::Char(c) if Param::by_key(c).is_some() => Choose(Param::by_key(c)?),
        KeyCode::Char('m') => NextParam,
        KeyCode::Char('+') | KeyCode::Char('=') => Adjust {
            up: true,
            coarse: false,
        },
        KeyCode::Char('-') | KeyCode::Char('_') => Adjust {
            up: false,
            coarse: false,
        },
        KeyCode::Char(']') => Adjust {
            up: true,
            coarse: true,
        },
        KeyCode::Char('[') => Adjust {
            up: false,
            coarse: true,
        },
        KeyCode::Left => Orbit {
            yaw: -ORBIT_DEG,
            pitch: 0.0,
        },
        KeyCode::Right => Orbit {
            yaw: ORBIT_DEG,
            pitch: 0.0,
        },
        KeyCode::Up => Orbit {
            yaw: 0.0,
            pitch: ORBIT_DEG,
        },
        KeyCode::Down => Orbit {
            yaw: 0.0,
            pitch: -ORBIT_DEG,
        },
        KeyCode::Char('i') => Move(MOVE_STEP, 0.0, 0.0),
        KeyCode::Char('k') => Move(-MOVE_STEP, 0.0, 0.0),
        KeyCode::Char('j') => Move(0.0, -MOVE_STEP, 0.0),
        KeyCode::Char('l') => Move(0.0, MOVE_STEP, 0.0),
        KeyCode::Char('u') => Move(0.0, 0.0, MOVE_STEP),
        KeyCode::Char('n') => Move(0.0, 0.0, -MOVE_STEP),
        KeyCode::Char('z') => Zoom(ZOOM_STEP),
        KeyCode::Char('x') => Zoom(1.0 / ZOOM_STEP),
        KeyCode::Char(',') => RotateSky(-SKY_TURN_DEG),
        KeyCode::Char('.') => RotateSky(SKY_TURN_DEG),
        KeyCode::Char('<') => ScaleSky(1.0 / SKY_SCALE),
        KeyCode::Char('>') => ScaleSky(SKY_SCALE),
        KeyCode::Char('f') => FocusOnSelected,
        KeyCode::Char('r') => ResetAccumulation,
        KeyCode::Char('R') => Revert,
        KeyCode::Char('p') => SavePng,
        KeyCode::Char('w') => WriteScene,
        KeyCode::Char('c') => CycleCells,
        KeyCode::Char('e') => ToggleNee,
        KeyCode::Char('d') => ToggleDenoise,
        KeyCode::Char('?') => ToggleHelp,
        KeyCode::Char('q') => Quit,
        KeyCode::Esc => Back,
        _ => return None,
    })
}
