//! The preview's frames, whichever backend makes them: on a GPU its resolve pass (the small
//! image the terminal shows and its noise estimate, read back asynchronously through
//! staging slots) and its denoiser pass; elsewhere the host's resolve and filter. With
//! several devices, every device's sums are added: uploaded to the GPU's resolve pass when
//! they have changed, or added on the host. The render thread (`ui::worker`) decides when a
//! frame is due; this decides how it is made, so that the preview never names a backend.

use super::{Backend, Renderer};
use crate::common::Resolved;
use crate::common::accum::{Sums, decode};
use crate::gpu::denoise::DenoisePass;
use crate::gpu::resolve::{ResolvePass, SLOTS};
use std::sync::Arc;

/// What [`Frames::request`] did.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Requested {
    /// A frame is made or on its way (false: the GPU's staging slots are all busy; ask again).
    pub made: bool,
    /// The other devices' sums were uploaded to the GPU's resolve pass for it.
    pub uploaded: bool,
}

/// The frame makers of one device, and the frames on their way; `T` tags a frame with what
/// the caller needs to know when it lands.
pub struct Frames<T> {
    backend: Backend,
    /// The GPU's resolve pass (on the CPU tracer frames are made on the host at once).
    resolve: Option<ResolvePass>,
    /// The GPU's denoiser, made on the first denoised frame (on the CPU tracer the host's
    /// filter denoises).
    denoiser: Option<DenoisePass>,
    /// A frame made on the host, waiting to be taken.
    host: Option<(T, Resolved)>,
    /// The frame each staging slot is bringing back, with the invalid samples of the other
    /// devices whose sums the resolve pass added.
    pending: [Option<(T, u64)>; SLOTS],
    /// The other devices' sums last uploaded to the resolve pass.
    uploaded: Vec<Arc<Sums>>,
}

impl<T: Copy> Frames<T> {
    pub fn new(backend: &Backend) -> Frames<T> {
        Frames {
            resolve: backend.gpu().map(|ctx| ResolvePass::new(ctx)),
            backend: backend.clone(),
            denoiser: None,
            host: None,
            pending: [None; SLOTS],
            uploaded: Vec::new(),
        }
    }

    /// Forgets the other devices' sums (after a restart, or when one of them failed): frames
    /// from now on leave them out until they are given again.
    pub fn clear_extra(&mut self) {
        if let Some(r) = &mut self.resolve {
            r.clear_extra();
        }
        self.uploaded.clear();
    }

    /// Whether a frame is waiting to be taken or on its way back.
    pub fn pending(&self) -> bool {
        self.host.is_some() || self.pending.iter().any(Option::is_some)
    }

    /// Makes a frame of `renderer`'s accumulation with `parts` (the other devices' sums)
    /// added, denoised or not, averaging `factor × factor` traced pixels per image pixel. A
    /// denoised frame needs the renderer's guides made first (`Renderer::make_guides`).
    pub fn request(
        &mut self,
        renderer: &mut Renderer,
        parts: &[Arc<Sums>],
        denoise: bool,
        factor: u32,
        tag: T,
    ) -> Requested {
        let mut done = Requested::default();
        let mut extra_invalid = 0;
        let summed = match (&self.backend, &mut self.resolve) {
            // The GPU's resolve pass adds the others' sums, uploaded when they have changed.
            (Backend::Gpu(ctx), Some(resolve)) if !denoise => {
                let changed = parts.len() != self.uploaded.len()
                    || parts
                        .iter()
                        .zip(&self.uploaded)
                        .any(|(a, b)| !Arc::ptr_eq(a, b));
                if !parts.is_empty() && changed {
                    // One helper's sums are uploaded as they are; several are added first.
                    let added;
                    let sums: &Sums = match parts {
                        [one] => one,
                        [first, rest @ ..] => {
                            added = rest.iter().fold((**first).clone(), |mut t, part| {
                                t.add(part);
                                t
                            });
                            &added
                        }
                        [] => unreachable!("some parts"),
                    };
                    resolve.set_extra(ctx, &sums.even, &sums.odd);
                    self.uploaded = parts.to_vec();
                    done.uploaded = true;
                }
                extra_invalid = parts.iter().map(|s| s.invalid).sum();
                None
            }
            _ => (!parts.is_empty()).then(|| {
                let mut total = renderer.exact_sums();
                for part in parts {
                    total.add(part);
                }
                total
            }),
        };
        let s = renderer.settings();
        let size = (s.width, s.height);
        let frame = if denoise {
            Some(match summed {
                // Several devices' sums, on the host.
                Some(Sums { even, odd, invalid }) => {
                    let d =
                        crate::denoise::denoise(&decode(&even), &decode(&odd), renderer.guides());
                    d.resolved(factor, invalid)
                }
                None => match (
                    &self.backend,
                    renderer.accumulation(),
                    renderer.guide_buffer(),
                ) {
                    // On the GPU, where the sums and the guides are (shaders/denoise.wgsl).
                    (Backend::Gpu(ctx), Some(accum), Some(guides)) => {
                        let pass = self.denoiser.get_or_insert_with(|| DenoisePass::new(ctx));
                        let tiles = pass.run(ctx, accum, guides, size, factor);
                        crate::denoise::from_tiles(tiles, size, factor)
                    }
                    _ => {
                        let snap = renderer.snapshot();
                        let d = crate::denoise::denoise(
                            &snap.data.even,
                            &snap.data.odd,
                            renderer.guides(),
                        );
                        d.resolved(factor, snap.data.invalid)
                    }
                },
            })
        } else if let Some(Sums { even, odd, invalid }) = summed {
            Some(Resolved::from_sums(&even, &odd, size, factor, invalid))
        } else {
            renderer.resolve_on_host(factor)
        };
        if let Some(frame) = frame {
            self.host = Some((tag, frame));
            done.made = true;
            return done;
        }
        let (Some(resolve), Backend::Gpu(ctx), Some(accum)) =
            (&mut self.resolve, &self.backend, renderer.accumulation())
        else {
            return done;
        };
        if let Some(slot) = resolve.request(ctx, accum, size, factor) {
            self.pending[slot] = Some((tag, extra_invalid));
            done.made = true;
        }
        done
    }

    /// The frame made on the host, if one waits.
    pub fn take_host(&mut self) -> Option<(T, Resolved)> {
        self.host.take()
    }

    /// The GPU's frames that have landed, in slot order; `block` waits for the GPU's work to
    /// finish first (when nothing else is left to do).
    pub fn take_landed(&mut self, block: bool) -> Vec<(T, Resolved)> {
        let (Some(resolve), Backend::Gpu(ctx)) = (&mut self.resolve, &self.backend) else {
            return Vec::new();
        };
        let poll = if block {
            wgpu::PollType::wait_indefinitely()
        } else {
            wgpu::PollType::Poll
        };
        let _ = ctx.device.poll(poll);
        let mut landed = Vec::new();
        for slot in 0..SLOTS {
            let Some((tag, extra_invalid)) = self.pending[slot] else {
                continue;
            };
            if !resolve.ready(slot) {
                continue;
            }
            self.pending[slot] = None;
            if let Some(mut resolved) = resolve.take(slot) {
                resolved.invalid += extra_invalid;
                landed.push((tag, resolved));
            }
        }
        landed
    }
}
