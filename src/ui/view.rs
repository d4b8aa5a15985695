//! Drawing the preview: the image cells, two status lines, the help overlay.

use super::app::{App, Mode, fmt_value};
use super::keys::{Param, help_lines};
use crate::output::cells::{Cell, CellColor};
use crate::scene::params::Group;
use ratatui::buffer::Buffer;
use ratatui::layout::Rect;
use ratatui::style::{Color, Modifier, Style};
use ratatui::text::{Line, Span};
use ratatui::widgets::{Block, Clear, Paragraph, Widget};

/// Where the image and the status lines go in a terminal of `area`: two status lines when
/// there is room for an image beside them, one on a short terminal, none below three rows.
pub fn split(area: Rect) -> (Rect, Rect) {
    let status_rows = match area.height {
        0..=2 => 0,
        3..=5 => 1,
        _ => 2,
    };
    let image = Rect {
        height: area.height - status_rows,
        ..area
    };
    let status = Rect {
        y: area.y + image.height,
        height: status_rows,
        ..area
    };
    (image, status)
}

/// The encoded preview, as last drawn: cells whose colour moved less than a threshold keep
/// their previous colour, so the terminal diff does not resend them.
#[derive(Clone, Debug, Default)]
pub struct Grid {
    pub cols: u16,
    pub rows: u16,
    pub cells: Vec<Cell>,
}

fn close(a: CellColor, b: CellColor, threshold: u8) -> bool {
    match (a, b) {
        (CellColor::Rgb(x), CellColor::Rgb(y)) => (0..3).all(|c| x[c].abs_diff(y[c]) <= threshold),
        (x, y) => x == y,
    }
}

impl Grid {
    /// Takes a new frame; returns how many cells changed beyond the threshold.
    pub fn update(&mut self, cols: u16, rows: u16, cells: Vec<Cell>, threshold: u8) -> usize {
        let thresholds = vec![threshold; cells.len()];
        self.update_at_most(cols, rows, cells, &thresholds, usize::MAX)
            .0
    }

    /// Like `update`, with a threshold per cell (its own noise, `cells::noise_thresholds`),
    /// changing at most `limit` cells, those that changed most (a frame sized to a slow
    /// link); returns (cells changed, cells left for a later frame).
    pub fn update_at_most(
        &mut self,
        cols: u16,
        rows: u16,
        cells: Vec<Cell>,
        thresholds: &[u8],
        limit: usize,
    ) -> (usize, usize) {
        if (cols, rows) != (self.cols, self.rows) || self.cells.len() != cells.len() {
            if limit >= cells.len() {
                *self = Grid { cols, rows, cells };
                return (self.cells.len(), 0);
            }
            // A new size on a slow link: from blank cells, as much as the limit allows.
            let blank = Cell {
                glyph: ' ',
                fg: CellColor::Default,
                bg: CellColor::Default,
            };
            *self = Grid {
                cols,
                rows,
                cells: vec![blank; cells.len()],
            };
        }
        // (how much, index) of every cell that moved beyond the threshold.
        let mut moved: Vec<(u8, usize)> = self
            .cells
            .iter()
            .zip(&cells)
            .enumerate()
            .filter(|(i, (old, new))| {
                let threshold = thresholds.get(*i).copied().unwrap_or(0);
                old.glyph != new.glyph
                    || !close(old.fg, new.fg, threshold)
                    || !close(old.bg, new.bg, threshold)
            })
            .map(|(i, (old, new))| (change(old, new), i))
            .collect();
        let left = moved.len().saturating_sub(limit);
        if left > 0 {
            moved.select_nth_unstable_by(limit, |a, b| b.0.cmp(&a.0));
            moved.truncate(limit);
        }
        for &(_, i) in &moved {
            self.cells[i] = cells[i];
        }
        (moved.len(), left)
    }
}

/// How far a cell moved: the largest channel difference of its colours (255 for a new
/// glyph or a colour of another kind).
fn change(a: &Cell, b: &Cell) -> u8 {
    let d = |x: CellColor, y: CellColor| match (x, y) {
        (CellColor::Rgb(p), CellColor::Rgb(q)) => {
            (0..3).map(|c| p[c].abs_diff(q[c])).max().unwrap_or(0)
        }
        (x, y) if x == y => 0,
        _ => 255,
    };
    if a.glyph != b.glyph {
        255
    } else {
        d(a.fg, b.fg).max(d(a.bg, b.bg))
    }
}

fn color(c: CellColor) -> Color {
    match c {
        CellColor::Rgb([r, g, b]) => Color::Rgb(r, g, b),
        CellColor::Indexed(i) => Color::Indexed(i),
        CellColor::Default => Color::Reset,
    }
}

/// The image cells, drawn at the top-left of the area they are given.
pub struct ImageWidget<'a>(pub &'a Grid);

impl Widget for ImageWidget<'_> {
    fn render(self, area: Rect, buf: &mut Buffer) {
        let g = self.0;
        for row in 0..g.rows.min(area.height) {
            for col in 0..g.cols.min(area.width) {
                let c = g.cells[row as usize * g.cols as usize + col as usize];
                buf[(area.x + col, area.y + row)]
                    .set_char(c.glyph)
                    .set_fg(color(c.fg))
                    .set_bg(color(c.bg));
            }
        }
    }
}

const SEP: &str = " │ ";

fn duration(d: std::time::Duration) -> String {
    let s = d.as_secs_f64();
    if s < 60.0 {
        format!("{s:.1} s")
    } else {
        format!("{}:{:02}", (s / 60.0) as u64, s as u64 % 60)
    }
}

fn rate(r: f64) -> String {
    if r >= 1e9 {
        format!("{:.2} Gs/s", r / 1e9)
    } else if r >= 1e6 {
        format!("{:.2} Ms/s", r / 1e6)
    } else {
        format!("{:.0} ks/s", r / 1e3)
    }
}

/// The columns `spans` take (a character each).
fn text_width(spans: &[Span]) -> usize {
    spans.iter().map(|x| x.content.chars().count()).sum()
}

/// First status line: a fresh message and the background save first (they are what the
/// user is waiting for), then what renders and how fast. When `width` is too narrow for all,
/// the adapter, the graphics mode, the image size and the time go, in that order, so that the
/// samples, the rate and the noise stay in view (`bench --preview` reads the size and time
/// where they fit).
pub fn stats_line(app: &App, width: u16) -> Line<'static> {
    let s = &app.stats;
    // (text, when it goes: 0 never, else the lowest first).
    let mut parts = vec![
        (format!(" {}", app.scene.short_name()), 0),
        (app.adapter.clone(), 1),
        (app.graphics.clone(), 2),
        (format!("{}×{}", s.width, s.height), 3),
        (format!("{} spp", s.spp), 0),
        (rate(s.samples_per_second), 0),
        (duration(s.elapsed), 4),
    ];
    // The raw image's estimated error (rough, and why, where few samples or a few pixels
    // make it), and the denoised image's after an arrow (as rough as the raw one).
    let text = match (s.noise, s.denoised, s.doubt) {
        (Some(n), Some(d), Some(why)) => format!("noise {}", why.pair_text(n, d)),
        (Some(n), Some(d), None) => format!("noise {:.2}% → {}", n * 100.0, d.text()),
        (Some(n), None, Some(why)) => format!("noise {}", why.text(n)),
        (Some(n), None, None) => format!("noise {:.2}%", n * 100.0),
        (None, _, _) => "noise –".into(),
    };
    parts.push((text, 0));
    if s.reached {
        parts.push(("target reached".into(), 0));
    }
    if s.invalid > 0 {
        parts.push((format!("{} invalid", s.invalid), 0));
    }
    if !app.nee {
        parts.push(("NEE off".into(), 0));
    }
    if let Some(link) = &app.link {
        parts.push((link.clone(), 0));
    }
    let mut spans = Vec::new();
    if let Some(m) = app.current_message() {
        let style = if m.starts_with("error") {
            Color::Red
        } else {
            Color::Green
        };
        spans.push(Span::styled(
            format!(" {m} "),
            Style::new().fg(Color::Black).bg(style),
        ));
    }
    if let Some(sv) = &app.saving {
        spans.push(Span::styled(
            format!(" saving {} {}/{} spp ", sv.path, sv.done, sv.total),
            Style::new().fg(Color::Black).bg(Color::Yellow),
        ));
    }
    let room = (width as usize).saturating_sub(text_width(&spans));
    let joined = |parts: &[(String, u8)]| {
        parts
            .iter()
            .map(|(t, _)| t.as_str())
            .collect::<Vec<_>>()
            .join(SEP)
    };
    for level in 1..=4 {
        if joined(&parts).chars().count() <= room {
            break;
        }
        parts.retain(|&(_, l)| l != level);
    }
    spans.push(Span::raw(joined(&parts)));
    Line::from(spans)
}

/// Second status line: the selected object and every adjustable value, the active one
/// highlighted. When `width` is too narrow for all, the camera's values that are not active
/// go first, then the help hint.
pub fn params_line(app: &App, width: u16) -> Line<'static> {
    let full = params_spans(app, true, true);
    let fits = |s: &Vec<Span>| text_width(s) <= width as usize;
    if fits(&full) {
        return Line::from(full);
    }
    let no_camera = params_spans(app, false, true);
    if fits(&no_camera) {
        return Line::from(no_camera);
    }
    Line::from(params_spans(app, false, false))
}

fn params_spans(app: &App, camera: bool, hint: bool) -> Vec<Span<'static>> {
    let mut spans = vec![Span::styled(
        format!(" ▸ {}", app.selected_label()),
        Style::new().add_modifier(Modifier::BOLD),
    )];
    let mut previous = None;
    for p in Param::all() {
        let spec = p.spec();
        if !camera && !p.is_material() && p != app.active_param() {
            continue;
        }
        let Some(v) = app.value(p) else { continue };
        // A group's colour channels stand closer together: `r 0.5 g 0.5 b 0.5`.
        let close = spec.group == Group::Colour && previous == Some(Group::Colour);
        spans.push(Span::raw(if close { " " } else { "  " }));
        previous = Some(spec.group);
        let label = spec.label;
        let text = format!("{label} {}", fmt_value(v));
        if p == app.active_param() {
            spans.push(Span::styled(
                text,
                Style::new().add_modifier(Modifier::REVERSED),
            ));
        } else {
            spans.push(Span::raw(text));
        }
    }
    if hint {
        spans.push(Span::styled(
            "   ? help",
            Style::new().add_modifier(Modifier::DIM),
        ));
    }
    spans
}

/// The key help, centred over `area`.
pub fn help(area: Rect, buf: &mut Buffer) {
    let bindings = help_lines();
    let key_width = bindings
        .iter()
        .map(|(keys, _)| keys.chars().count())
        .max()
        .unwrap_or(0);
    let help_width = bindings
        .iter()
        .map(|(_, help)| help.chars().count())
        .max()
        .unwrap_or(0);
    // A space, the keys, two spaces, the help, a space; plus the two borders.
    let width = (1 + key_width + 2 + help_width + 1 + 2) as u16;
    let height = bindings.len() as u16 + 2;
    let w = width.min(area.width);
    let h = height.min(area.height);
    let r = Rect {
        x: area.x + (area.width - w) / 2,
        y: area.y + (area.height - h) / 2,
        width: w,
        height: h,
    };
    Clear.render(r, buf);
    let lines: Vec<Line> = bindings
        .iter()
        .map(|(keys, help)| {
            Line::from(vec![
                Span::styled(
                    format!(" {keys:>key_width$}"),
                    Style::new().add_modifier(Modifier::BOLD),
                ),
                Span::raw(format!("  {help}")),
            ])
        })
        .collect();
    Paragraph::new(lines)
        .block(Block::bordered().title(" keys (? or Esc closes) "))
        .render(r, buf);
}

/// The whole screen.
pub fn draw(app: &App, grid: &Grid, area: Rect, buf: &mut Buffer) {
    let (image, status) = split(area);
    ImageWidget(grid).render(image, buf);
    if status.height >= 1 {
        let first = Rect {
            height: 1,
            ..status
        };
        Paragraph::new(stats_line(app, first.width)).render(first, buf);
    }
    if status.height >= 2 {
        let second = Rect {
            y: status.y + 1,
            height: 1,
            ..status
        };
        Paragraph::new(params_line(app, second.width)).render(second, buf);
    }
    if app.mode == Mode::Help {
        help(area, buf);
    }
}
