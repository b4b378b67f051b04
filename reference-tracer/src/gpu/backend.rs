//! The GPU tracer as a [`Backend`]: the scene (and the guide) go up at the first
//! render, the guide comes home after each.

use super::{GpuContext, GpuGuide, GpuTracer};
use crate::backend::{Backend, RenderResult};
use crate::integrator::Method;
use crate::learners::SessionLearners;
use crate::render::{Progress, RenderSettings};
use crate::scene::Scene;
use crate::schedule::Schedule;

/// The GPU tracer of a session, started at its first render.
#[derive(Default)]
pub struct GpuBackend {
    tracer: Option<GpuTracer>,
}

impl Backend for GpuBackend {
    fn render(
        &mut self,
        scene: &Scene,
        learners: &mut SessionLearners,
        settings: &RenderSettings,
        on_pass: &mut dyn FnMut(&Progress<'_>),
    ) -> RenderResult {
        let integrator = &settings.integrator;
        let method = integrator.method;
        if integrator.nee_kickstart && method == Method::Guided {
            return Err("--nee-kickstart on: the GPU tracer's guided method has no next-event estimation \
                        to learn from (use --nee-kickstart off)"
                .into());
        }
        let guide = learners.guide_for_mut(method);
        if guide.is_some() && settings.schedule != Schedule::Online {
            return Err("the GPU tracer learns online only (--schedule online)".into());
        }
        if guide.is_some() && integrator.guide_depth != u32::MAX {
            return Err("the GPU tracer guides every vertex (leave out --guide-depth)".into());
        }
        if method.uses_guide() && integrator.focal_probability > 0.0 {
            return Err("the GPU tracer has no focal guide yet (leave out --p-focal)".into());
        }
        if guide.is_some() && integrator.learned_guide_share {
            return Err("the GPU tracer has no learned guide share (--guide-share fixed)".into());
        }
        // Refused before the GPU starts: a structure it has no buffers for.
        let uploaded = guide.as_deref().map(GpuGuide::of).transpose()?;
        let tracer = match &mut self.tracer {
            Some(tracer) => tracer,
            empty => {
                let context = GpuContext::new()?;
                eprintln!("gpu: {}", context.describe());
                empty.insert(GpuTracer::new(context, scene, integrator, uploaded)?)
            }
        };
        let result = tracer.render(settings, on_pass)?;
        if let Some(guide) = guide {
            tracer.download(guide)?;
        }
        Ok(result)
    }
}
