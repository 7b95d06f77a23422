//! A headless OpenGL ES 3.0 context through EGL, for the native GL backend: no window, no
//! display server, no GPU needed (Mesa's llvmpipe answers on a machine without one).
//!
//! libEGL is loaded at run time (`khronos-egl`'s `dynamic` feature), so a machine without it
//! gets an [`EglError`] rather than a binary that does not start. The display is the
//! surfaceless Mesa platform when EGL offers it, else the default display; the context is
//! made current with no surfaces (the renderer draws into its own framebuffer objects).

use std::marker::PhantomData;

use khronos_egl as egl;

/// `EGL_PLATFORM_SURFACELESS_MESA`.
const PLATFORM_SURFACELESS_MESA: egl::Enum = 0x31DD;

/// Why no headless GL context could be created.
#[derive(Debug, thiserror::Error)]
pub enum EglError {
    #[error(
        "cannot load libEGL (install libegl1 and a driver, e.g. Debian's libegl-mesa0 libgles2 libgl1-mesa-dri): {0}"
    )]
    Library(String),
    #[error(
        "EGL offers no usable display (is a GL driver installed, e.g. Debian's libegl-mesa0 and libgl1-mesa-dri?): {0}"
    )]
    NoDisplay(String),
    #[error("EGL has no OpenGL ES 3 configuration (the GL driver does not support OpenGL ES 3.0)")]
    NoConfig,
    #[error("EGL {what} failed: {error}")]
    Call { what: &'static str, error: egl::Error },
}

type Instance = egl::DynamicInstance<egl::EGL1_4>;

/// An OpenGL ES 3.0 context with no surface, current on the thread that created it.
///
/// Not `Send`: a GL context is current on one thread, and GL objects must be used there.
pub struct HeadlessContext {
    egl: Instance,
    display: egl::Display,
    context: egl::Context,
    _not_send: PhantomData<*const ()>,
}

impl std::fmt::Debug for HeadlessContext {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("HeadlessContext").field("display", &self.display).field("context", &self.context).finish()
    }
}

impl HeadlessContext {
    /// Loads libEGL, creates an OpenGL ES 3.0 context and makes it current on this thread.
    pub fn new() -> Result<HeadlessContext, EglError> {
        // SAFETY: loading the system's libEGL; its symbols follow the EGL specification.
        let egl = unsafe { Instance::load_required() }.map_err(|e| EglError::Library(e.to_string()))?;
        let display = Self::display(&egl)?;
        egl.bind_api(egl::OPENGL_ES_API).map_err(|error| EglError::Call { what: "eglBindAPI(OPENGL_ES)", error })?;
        // SURFACE_TYPE defaults to WINDOW_BIT, which a surfaceless display has no config for: 0
        // (a mask with no bits) accepts any.
        let attributes = [egl::RENDERABLE_TYPE, egl::OPENGL_ES3_BIT, egl::SURFACE_TYPE, 0, egl::NONE];
        let config = egl
            .choose_first_config(display, &attributes)
            .map_err(|error| EglError::Call { what: "eglChooseConfig", error })?
            .ok_or(EglError::NoConfig)?;
        // EGL_CONTEXT_CLIENT_VERSION (EGL 1.3+) = EGL_CONTEXT_MAJOR_VERSION (1.5); minor defaults to 0.
        let context_attributes = [egl::CONTEXT_CLIENT_VERSION, 3, egl::NONE];
        let context = egl
            .create_context(display, config, None, &context_attributes)
            .map_err(|error| EglError::Call { what: "eglCreateContext (OpenGL ES 3.0)", error })?;
        let headless = HeadlessContext { egl, display, context, _not_send: PhantomData };
        headless.make_current()?;
        Ok(headless)
    }

    /// An initialised display: the surfaceless Mesa platform (EGL 1.5's `eglGetPlatformDisplay`)
    /// when it works, else the default display.
    fn display(egl: &Instance) -> Result<egl::Display, EglError> {
        let mut failures = Vec::new();
        if let Some(egl15) = egl.upcast::<egl::EGL1_5>() {
            // SAFETY: the surfaceless platform takes EGL_DEFAULT_DISPLAY as its native display.
            match unsafe {
                egl15.get_platform_display(PLATFORM_SURFACELESS_MESA, egl::DEFAULT_DISPLAY, &[egl::ATTRIB_NONE])
            } {
                Ok(d) => match egl.initialize(d) {
                    Ok(_) => return Ok(d),
                    Err(e) => failures.push(format!("surfaceless platform: eglInitialize: {e}")),
                },
                Err(e) => failures.push(format!("surfaceless platform: {e}")),
            }
        } else {
            failures.push("surfaceless platform: libEGL is older than EGL 1.5".into());
        }
        // SAFETY: EGL_DEFAULT_DISPLAY is always a valid argument.
        match unsafe { egl.get_display(egl::DEFAULT_DISPLAY) } {
            Some(d) => match egl.initialize(d) {
                Ok(_) => return Ok(d),
                Err(e) => failures.push(format!("default display: eglInitialize: {e}")),
            },
            None => failures.push("default display: none".into()),
        }
        Err(EglError::NoDisplay(failures.join("; ")))
    }

    /// Makes this context current on the calling thread (with no surfaces).
    pub fn make_current(&self) -> Result<(), EglError> {
        self.egl
            .make_current(self.display, None, None, Some(self.context))
            .map_err(|error| EglError::Call { what: "eglMakeCurrent (no surface)", error })
    }

    /// Whether this context is the calling thread's current one.
    pub fn is_current(&self) -> bool {
        self.egl.get_current_context().is_some_and(|c| c.as_ptr() == self.context.as_ptr())
    }

    /// A glow context over this EGL context's function pointers. Call it while this context is
    /// current (as it is after [`new`](Self::new)).
    pub fn glow(&self) -> glow::Context {
        // SAFETY: the pointers come from this EGL instance; `glow` calls them with the GL ES
        // signatures EGL documents, on this (current) context.
        unsafe {
            glow::Context::from_loader_function(|name| {
                self.egl.get_proc_address(name).map_or(std::ptr::null(), |f| f as *const std::ffi::c_void)
            })
        }
    }
}

impl Drop for HeadlessContext {
    fn drop(&mut self) {
        if self.is_current() {
            let _ = self.egl.make_current(self.display, None, None, None);
        }
        let _ = self.egl.destroy_context(self.display, self.context);
        // The display is not terminated: EGL hands every caller the same display for the same
        // platform, and terminating it would pull it from under other live contexts.
    }
}
