//! The live preview: three threads and one event channel. The input thread reads terminal
//! events, the render thread (`worker`) owns the GPU and sends frames, a signal handler
//! sends SIGTERM/SIGHUP; the UI thread (here) only updates the [`app::App`] and draws, so
//! input never waits on the GPU.

pub mod app;
pub mod detect;
mod error;
mod event;
mod event_loop;
pub mod flow;
pub mod graphics;
pub mod input;
pub mod keys;
mod save;
mod screen;
mod setup;
pub mod term;
pub mod view;
pub mod worker;

pub use event::Event;
pub use save::{edited_scene_path, free_png_path, write_scene};
pub use setup::{Graphics, ViewOptions};

use app::App;
pub use error::ViewError;
use event::spawn_input;
use event_loop::print_stats;
use ratatui::Terminal;
use ratatui::backend::CrosstermBackend;
use screen::Ui;
use setup::{choose_graphics, setup};
use std::process::ExitCode;
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};
use view::Grid;
use worker::WorkerOptions;

/// Opens the preview; returns when the user quits.
pub fn run(opts: ViewOptions) -> Result<ExitCode, ViewError> {
    let setup = setup(&opts)?;
    let (tx, rx) = std::sync::mpsc::channel::<Event>();
    let signal_tx = tx.clone();
    let _ = ctrlc::set_handler(move || {
        let _ = signal_tx.send(Event::Signal);
    });
    let guard = term::TerminalGuard::enter(opts.log.as_deref())?;
    let (graphics, graphics_note, graphics_why) = choose_graphics(&opts);
    if let Some(g) = graphics {
        term::set_clear(g.clear());
    }
    spawn_input(tx.clone())?;
    let (to_worker, worker) = worker::spawn(
        setup.backends,
        WorkerOptions {
            fps: opts.fps,
            max_spp: opts.max_spp,
            target_error: opts.target_error,
            generic: opts.generic,
            denoise: opts.denoise,
        },
        tx,
    );
    let bytes = Arc::new(AtomicU64::new(0));
    let mut terminal = Terminal::new(CrosstermBackend::new(term::CountingWriter::new(
        bytes.clone(),
    )))?;
    let mut ui = Ui {
        app: App {
            denoise: opts.denoise,
            denoise_on: match opts.denoise {
                crate::denoise::Mode::Off => crate::denoise::Mode::Auto,
                m => m,
            },
            ..App::new(setup.scene, setup.adapter, setup.cells)
        },
        opts: opts.clone(),
        color: setup.color,
        graphics,
        sent_image: None,
        image_due: Vec::new(),
        scale_settled: false,
        image_bytes_per_pixel: 1.0,
        grid: Grid::default(),
        to_worker,
        generation: 0,
        fresh_image: false,
        urgent: false,
        edit_frame: false,
        sent_coarse: false,
        pending_bands: Vec::new(),
        shown_generation: 0,
        flow: flow::Flow::default(),
        bytes_per_cell: 40.0,
        cells_changed: 0,
        cells_left: 0,
        quiet_frames: 0,
        exact: false,
        quit: false,
        farewell: Vec::new(),
    };
    // Why there are no pixel graphics, where the user may have wanted them.
    if let Some(why) = graphics_why {
        ui.app.say(format!("graphics: cells ({why})"));
    }
    ui.app.graphics = graphics_note;
    let history = ui.event_loop(&mut terminal, &rx, &bytes);
    ui.shutdown(worker, &rx);
    drop(terminal);
    drop(guard);
    for m in &ui.farewell {
        eprintln!("{m}");
    }
    let history = history?;
    if opts.stats {
        print_stats(&history, bytes.load(Ordering::Relaxed), &ui.app.stats);
    }
    Ok(ExitCode::SUCCESS)
}
