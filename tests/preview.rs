//! The preview as the terminal receives it, without a GPU: cell encoding checked cell by
//! cell in a ratatui Buffer, and whole screens as insta snapshots of a TestBackend.

use ratatui::Terminal;
use ratatui::backend::TestBackend;
use ratatui::buffer::Buffer;
use ratatui::layout::Rect;
use ratatui::style::Color;
use ratatui::widgets::Widget;
use termtrace::output::LinearImage;
use termtrace::output::cells::{self, CellMode, ColorMode};
use termtrace::scene::Scene;
use termtrace::ui::app::{App, Stats};
use termtrace::ui::keys::{Action, Param};
use termtrace::ui::view::{self, Grid, ImageWidget};

const WHITE: [f32; 3] = [1.0; 3];
const BLACK: [f32; 3] = [0.0; 3];

fn image(w: u32, h: u32, px: &[[f32; 3]]) -> LinearImage {
    LinearImage {
        width: w,
        height: h,
        pixels: px.to_vec(),
    }
}

/// Encodes `img` and draws it into a buffer of its cell size.
fn draw(img: &LinearImage, mode: CellMode, color: ColorMode) -> Buffer {
    let (sx, sy) = mode.subpixels();
    let (cols, rows) = ((img.width / sx) as u16, (img.height / sy) as u16);
    let mut grid = Grid::default();
    grid.update(cols, rows, cells::encode(img, mode, color), 0);
    let mut buf = Buffer::empty(Rect::new(0, 0, cols, rows));
    ImageWidget(&grid).render(buf.area, &mut buf);
    buf
}

fn cell(buf: &Buffer, x: u16, y: u16) -> (String, Color, Color) {
    let c = &buf[(x, y)];
    (c.symbol().to_string(), c.fg, c.bg)
}

#[test]
fn half_blocks_put_the_upper_pixel_in_fg_and_the_lower_in_bg() {
    let red = [1.0, 0.0, 0.0];
    let blue = [0.0, 0.0, 1.0];
    let buf = draw(
        &image(2, 2, &[red, WHITE, blue, BLACK]),
        CellMode::Half,
        ColorMode::Truecolor,
    );
    assert_eq!(
        cell(&buf, 0, 0),
        ("▀".into(), Color::Rgb(255, 0, 0), Color::Rgb(0, 0, 255))
    );
    assert_eq!(
        cell(&buf, 1, 0),
        ("▀".into(), Color::Rgb(255, 255, 255), Color::Rgb(0, 0, 0))
    );
}

#[test]
fn a_horizontal_edge_picks_the_upper_half_block() {
    let buf = draw(
        &image(2, 2, &[WHITE, WHITE, BLACK, BLACK]),
        CellMode::Quadrant,
        ColorMode::Truecolor,
    );
    assert_eq!(
        cell(&buf, 0, 0),
        ("▀".into(), Color::Rgb(255, 255, 255), Color::Rgb(0, 0, 0))
    );
    let buf = draw(
        &image(2, 2, &[BLACK, BLACK, WHITE, WHITE]),
        CellMode::Quadrant,
        ColorMode::Truecolor,
    );
    assert_eq!(
        cell(&buf, 0, 0),
        ("▄".into(), Color::Rgb(255, 255, 255), Color::Rgb(0, 0, 0))
    );
}

#[test]
fn a_quadrant_pattern_picks_its_quadrant_glyph() {
    let buf = draw(
        &image(2, 2, &[WHITE, BLACK, BLACK, WHITE]),
        CellMode::Quadrant,
        ColorMode::Truecolor,
    );
    assert_eq!(
        cell(&buf, 0, 0),
        ("▚".into(), Color::Rgb(255, 255, 255), Color::Rgb(0, 0, 0))
    );
    let buf = draw(
        &image(2, 2, &[BLACK, BLACK, WHITE, BLACK]),
        CellMode::Quadrant,
        ColorMode::Truecolor,
    );
    assert_eq!(cell(&buf, 0, 0).0, "▖");
}

#[test]
fn three_colours_in_a_quadrant_cell_split_to_the_least_error() {
    // Red, red, dark red, blue: the best split puts blue alone (the reds average together).
    let (r, dr, b) = ([1.0, 0.0, 0.0], [0.5, 0.0, 0.0], [0.0, 0.0, 1.0]);
    let buf = draw(
        &image(2, 2, &[r, r, dr, b]),
        CellMode::Quadrant,
        ColorMode::Truecolor,
    );
    let (glyph, fg, bg) = cell(&buf, 0, 0);
    let mean_red = termtrace::scene::color::linear_to_srgb((1.0 + 1.0 + 0.5) / 3.0) * 255.0;
    assert_eq!(glyph, "▛", "red in three quadrants");
    assert_eq!(fg, Color::Rgb(mean_red.round() as u8, 0, 0));
    assert_eq!(bg, Color::Rgb(0, 0, 255));
}

#[test]
fn sextants_pick_the_sextant_glyph() {
    // Left column and the upper-right pixel white: mask 0b010111 is BLOCK SEXTANT-1235.
    let px = [WHITE, WHITE, WHITE, BLACK, WHITE, BLACK];
    let buf = draw(&image(2, 3, &px), CellMode::Sextant, ColorMode::Truecolor);
    assert_eq!(
        cell(&buf, 0, 0),
        (
            "\u{1FB15}".into(),
            Color::Rgb(255, 255, 255),
            Color::Rgb(0, 0, 0)
        )
    );
}

#[test]
fn black_and_white_average_in_linear_light_to_srgb_188() {
    // Supersampling 2×2 black and white pixels into one: linear 0.5 encodes to sRGB 188
    // (averaging the encoded values would give 128).
    let fine = image(
        2,
        4,
        &[BLACK, WHITE, WHITE, BLACK, BLACK, WHITE, WHITE, BLACK],
    );
    let one = cells::downsample(&fine, 2);
    let buf = draw(&one, CellMode::Half, ColorMode::Truecolor);
    assert_eq!(
        cell(&buf, 0, 0),
        (
            "▀".into(),
            Color::Rgb(188, 188, 188),
            Color::Rgb(188, 188, 188)
        )
    );
}

#[test]
fn the_256_colour_fallback_uses_the_fixed_palette() {
    let buf = draw(
        &image(1, 2, &[[1.0, 0.0, 0.0], WHITE]),
        CellMode::Half,
        ColorMode::Ansi256,
    );
    assert_eq!(
        cell(&buf, 0, 0),
        ("▀".into(), Color::Indexed(196), Color::Indexed(231))
    );
}

#[test]
fn ascii_maps_luminance_to_a_ramp_without_colour() {
    let buf = draw(
        &image(3, 2, &[BLACK, [0.2; 3], WHITE, BLACK, [0.2; 3], WHITE]),
        CellMode::Ascii,
        ColorMode::None,
    );
    let glyphs: String = (0..3).map(|x| cell(&buf, x, 0).0).collect();
    assert_eq!(glyphs, " =@");
    assert_eq!(cell(&buf, 2, 0).1, Color::Reset);
}

#[test]
fn a_colour_that_barely_moved_is_not_resent() {
    let mut grid = Grid::default();
    let frame = |v: f32| {
        cells::encode(
            &image(1, 2, &[[v; 3], [v; 3]]),
            CellMode::Half,
            ColorMode::Truecolor,
        )
    };
    assert_eq!(grid.update(1, 1, frame(0.5), 2), 1);
    // 0.5 → 0.502 moves sRGB 188 to 188 or 189: within the threshold, the old colour stays.
    assert_eq!(grid.update(1, 1, frame(0.502), 2), 0);
    assert_eq!(grid.update(1, 1, frame(0.6), 2), 1);
}

fn app() -> App {
    let mut a = App::new(
        Scene::load("specular").unwrap(),
        "llvmpipe (Vulkan)".into(),
        CellMode::Half,
    );
    a.stats = Stats {
        width: 60,
        height: 28,
        spp: 128,
        samples_per_second: 1.25e6,
        elapsed: std::time::Duration::from_millis(3400),
        noise: Some(0.0312),
        denoised: Some(termtrace::common::resolved::Estimate::Value(0.0087)),
        doubt: None,
        invalid: 0,
        helped: 0,
        reached: false,
    };
    a
}

/// The first status line's text.
fn stats_text(a: &App) -> String {
    view::stats_line(a, 200)
        .spans
        .iter()
        .map(|s| s.content.as_ref())
        .collect()
}

#[test]
fn a_reached_target_error_is_said_on_the_status_line() {
    let text = stats_text;
    let mut a = app();
    assert!(!text(&a).contains("target reached"), "{}", text(&a));
    a.stats.reached = true;
    assert!(text(&a).contains("target reached"), "{}", text(&a));
}

#[test]
fn a_rough_noise_figure_is_shown_rounded_with_why() {
    // Fireflies holding the estimate: the status line shows no confident figure, but "~12%"
    // and why; with few samples likewise; a sound estimate keeps its two decimals.
    use termtrace::common::resolved::Doubt;
    let text = stats_text;
    let mut a = app();
    a.stats.noise = Some(0.1234);
    a.stats.denoised = None;
    assert!(text(&a).contains("noise 12.34%"), "{}", text(&a));
    a.stats.doubt = Some(Doubt::FewPixels);
    assert!(text(&a).contains("noise ~12% (fireflies)"), "{}", text(&a));
    // The denoised image's figure is as rough as the raw one it comes with.
    use termtrace::common::resolved::Estimate;
    a.stats.doubt = Some(Doubt::FewSamples);
    a.stats.denoised = Some(Estimate::Value(0.0087));
    assert!(
        text(&a).contains("noise ~12% → ~0.87% (few samples)"),
        "{}",
        text(&a)
    );
    a.stats.doubt = Some(Doubt::FewPixels);
    a.stats.denoised = Some(Estimate::Below(0.0041));
    assert!(
        text(&a).contains("noise ~12% → <0.41% (fireflies)"),
        "{}",
        text(&a)
    );
    // A sound raw estimate: both figures with their decimals.
    a.stats.doubt = None;
    a.stats.denoised = Some(Estimate::Value(0.0087));
    assert!(text(&a).contains("noise 12.34% → 0.87%"), "{}", text(&a));
}

/// A grid with a gradient, so the snapshot shows where the image goes.
fn gradient_grid(cols: u16, rows: u16) -> Grid {
    let (w, h) = (cols as u32, rows as u32 * 2);
    let px: Vec<[f32; 3]> = (0..w * h)
        .map(|i| {
            let (x, y) = (i % w, i / w);
            [x as f32 / w as f32, y as f32 / h as f32, 0.5]
        })
        .collect();
    let mut g = Grid::default();
    g.update(
        cols,
        rows,
        cells::encode(&image(w, h, &px), CellMode::Half, ColorMode::Truecolor),
        0,
    );
    g
}

fn screen(app: &App, w: u16, h: u16) -> Terminal<TestBackend> {
    let mut t = Terminal::new(TestBackend::new(w, h)).unwrap();
    let (img, _) = view::split(Rect::new(0, 0, w, h));
    let grid = gradient_grid(img.width, img.height);
    t.draw(|f| view::draw(app, &grid, f.area(), f.buffer_mut()))
        .unwrap();
    t
}

#[test]
fn screen_with_status_lines() {
    let mut a = app();
    a.apply(Action::SelectNext);
    a.apply(Action::SelectNext);
    a.apply(Action::Choose(Param::named("specular")));
    insta::assert_snapshot!(screen(&a, 100, 8).backend());
}

/// Both status lines keep what matters: the samples, rate and noise; the active value.
#[test]
fn narrow_screen_drops_inactive_camera_values() {
    let a = app();
    insta::assert_snapshot!(screen(&a, 60, 6).backend());
}

#[test]
fn help_overlay() {
    let mut a = app();
    a.apply(Action::ToggleHelp);
    insta::assert_snapshot!(screen(&a, 90, 24).backend());
}

#[test]
fn tiny_terminals_draw_without_panicking() {
    for (w, h) in [(1, 1), (2, 1), (1, 3), (5, 2), (10, 3), (3, 7)] {
        let mut a = app();
        screen(&a, w, h);
        a.apply(Action::ToggleHelp);
        screen(&a, w, h);
    }
    insta::assert_snapshot!(screen(&app(), 12, 3).backend());
}

#[test]
fn a_frame_over_budget_sends_the_most_changed_cells_first_and_the_rest_next() {
    let c = |v: u8| cells::Cell {
        glyph: '▀',
        fg: cells::CellColor::Rgb([v, v, v]),
        bg: cells::CellColor::Rgb([v, v, v]),
    };
    let mut grid = Grid::default();
    grid.update(4, 1, vec![c(0); 4], 0);
    let target = vec![c(10), c(200), c(50), c(120)];
    let thresholds = [2u8; 4];
    assert_eq!(
        grid.update_at_most(4, 1, target.clone(), &thresholds, 2),
        (2, 2)
    );
    assert_eq!(grid.cells, vec![c(0), c(200), c(0), c(120)]);
    assert_eq!(
        grid.update_at_most(4, 1, target.clone(), &thresholds, 2),
        (2, 0)
    );
    assert_eq!(grid.cells, target);
    // A change within a cell's threshold (its noise) is not sent at all.
    let mut nudged = target.clone();
    nudged[0] = c(14);
    assert_eq!(grid.update_at_most(4, 1, nudged, &[5, 2, 2, 2], 10), (0, 0));
}
