//! CAPTURE: stills of the output frame (and, configurable, the raw fisheye frame) as JPEG or
//! PNG, and recordings of the encoded stream to fragmented MP4. Files are named by local time
//! and a running index; free disk space is checked before anything starts, so a full disk is
//! an error reply rather than a truncated file. A MAVLink camera's stills and video are of
//! its view alone ([`ViewShooter`]): a still is asked for here, rendered by the frame loop,
//! written and reported back; a view's recording takes its own stream's access units.

use super::recording::{self, Disk, Running};
use crate::frame::PlaneLayout;
use crate::state::capture::{
    CaptureError, CaptureStatus, Capturer, Geotag, StillDone, ViewShooter,
};
use crate::state::{CaptureFailure, MAX_CAMERAS, Report};
use crate::stream::Recorder;
use crate::stream::encoder::AccessUnit;
use crate::stream::record::Container;
use crate::supervise::Locked;
use gstreamer::glib;
use serde::{Deserialize, Serialize};
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, AtomicU16, AtomicU32, Ordering};
use std::sync::mpsc::Sender;
use std::sync::{Arc, Mutex};
use std::time::Instant;
use tracing::{error, info};

#[derive(Clone, Copy, Debug, PartialEq, Eq, Deserialize, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum StillFormat {
    Jpeg,
    Png,
}

impl StillFormat {
    pub fn extension(self) -> &'static str {
        match self {
            StillFormat::Jpeg => "jpg",
            StillFormat::Png => "png",
        }
    }
}

#[derive(Clone, Debug, PartialEq, Deserialize, Serialize)]
#[serde(default, deny_unknown_fields)]
pub struct CaptureConfig {
    /// Where stills and recordings go (made if missing).
    pub dir: PathBuf,
    pub still_format: StillFormat,
    /// Also save the raw fisheye frame beside each still.
    pub raw: bool,
    /// A capture is refused while the disk has less free space than this.
    pub min_free_mb: u64,
    /// What recordings are written as: MP4, or MPEG-TS with the KLV metadata.
    pub container: Container,
    /// The recordings' coding: the encoder's (`[encoder] codec`), not a key of `[capture]`.
    #[serde(skip)]
    pub codec: crate::stream::Codec,
}

impl Default for CaptureConfig {
    fn default() -> Self {
        CaptureConfig {
            dir: "captures".into(),
            still_format: StillFormat::Jpeg,
            raw: false,
            min_free_mb: 200,
            container: Container::Mp4,
            codec: crate::stream::Codec::H264,
        }
    }
}

/// Why a still was not written.
#[derive(Debug, thiserror::Error)]
enum StillError {
    #[error(transparent)]
    Decode(#[from] crate::frame::FrameError),
    #[error(transparent)]
    Encode(#[from] image::ImageError),
    #[error(transparent)]
    Tags(#[from] super::geotag::GeotagError),
    #[error("{}: {source}", path.display())]
    Write {
        path: PathBuf,
        source: std::io::Error,
    },
}

/// A view's still asked for: the view, when it was asked for, and whom to tell.
pub type ViewStill = (usize, Instant, StillDone);

pub struct Capture {
    cfg: CaptureConfig,
    still_wanted: AtomicBool,
    /// Stills of single views asked for and not rendered yet.
    view_stills: Mutex<Vec<ViewStill>>,
    /// Recordings of single views' own streams, and whether each owes a key frame.
    view_recorders: Mutex<[Option<Running>; MAX_CAMERAS]>,
    view_key_wanted: [AtomicBool; MAX_CAMERAS],
    /// Set when the encoder should send a key frame (a recording starts).
    key_wanted: AtomicBool,
    recorder: Mutex<Option<Running>>,
    /// Where a recording that stopped, or a still not written, is reported.
    report: Arc<Report>,
    images: AtomicU16,
    videos: AtomicU16,
    index: AtomicU32,
    /// The stills' writer: one thread, so stills are written and announced in the order
    /// they were taken (two written side by side finished the other way round under load).
    writer: Mutex<Option<Sender<Job>>>,
}

/// A still's writing, run on the writer's thread.
type Job = Box<dyn FnOnce() + Send>;

/// One still to write: the output frame and, when asked for, the fisheye frame.
pub struct Still {
    pub output: (Vec<u8>, PlaneLayout),
    pub raw: Option<(Vec<u8>, PlaneLayout)>,
}

impl Capture {
    pub fn new(cfg: CaptureConfig, report: Arc<Report>) -> Capture {
        Capture {
            cfg,
            still_wanted: AtomicBool::new(false),
            view_stills: Mutex::default(),
            view_recorders: Mutex::default(),
            view_key_wanted: Default::default(),
            key_wanted: AtomicBool::new(false),
            recorder: Mutex::new(None),
            report,
            images: AtomicU16::new(0),
            videos: AtomicU16::new(0),
            index: AtomicU32::new(0),
            writer: Mutex::new(None),
        }
    }

    /// Runs `job` on the stills' writer, after those before it (the thread is started on
    /// the first, and again should it have ended, a panic in a job included), so the frame
    /// loop never waits on the disk.
    fn in_order(&self, job: Job) {
        let mut writer = self.writer.locked();
        let job = match writer.as_ref() {
            Some(w) => match w.send(job) {
                Ok(()) => return,
                Err(e) => e.0,
            },
            None => job,
        };
        let (tx, rx) = std::sync::mpsc::channel::<Job>();
        let started = std::thread::Builder::new()
            .name("stills".into())
            .spawn(move || rx.into_iter().for_each(|job| job()));
        if started.is_err() {
            error!("stills: no thread to write on; writing on the frame loop");
            return job();
        }
        // The thread reads until `tx` is dropped: this send cannot fail.
        let _ = tx.send(job);
        *writer = Some(tx);
    }

    pub fn wants_raw(&self) -> bool {
        self.cfg.raw
    }

    fn disk(&self) -> Disk<'_> {
        Disk {
            dir: &self.cfg.dir,
            min_free_mb: self.cfg.min_free_mb,
        }
    }

    /// The directory exists (made if missing) and has room; the error says why not.
    fn ready(&self) -> Result<(), CaptureError> {
        let dir = &self.cfg.dir;
        std::fs::create_dir_all(dir).map_err(|source| CaptureError::Directory {
            dir: dir.clone(),
            source,
        })?;
        let disk = self.disk();
        let free_mb = disk.free_mb()?;
        if free_mb < disk.needed_mb() {
            return Err(CaptureError::Full {
                dir: dir.clone(),
                free_mb,
                min_free_mb: disk.needed_mb(),
            });
        }
        Ok(())
    }

    /// A still was written (`Ok`), or not: the report says so until one works again.
    fn still_done<E: std::fmt::Display>(&self, written: &Result<(), E>) {
        let failure = written.as_ref().err().map(|e| CaptureFailure {
            brief: match self.disk().full() {
                true => "a still was not written: disk full".into(),
                false => "a still was not written: write error".into(),
            },
            why: format!("a still was not written: {e}"),
        });
        self.report.set_capture_failure(failure);
    }

    /// `captures/digiview-20261121-142503-0003.ext`
    fn name(&self, suffix: &str) -> PathBuf {
        // Local time of the UNIX time that never goes back: names sort as they were made.
        let unix_s = (crate::clock::utc_us() / 1_000_000) as i64;
        let when = glib::DateTime::from_unix_local(unix_s)
            .and_then(|t| t.format("%Y%m%d-%H%M%S"))
            .map(|s| s.to_string())
            .unwrap_or_else(|_| "now".into());
        let i = self.index.fetch_add(1, Ordering::Relaxed);
        self.cfg.dir.join(format!("digiview-{when}-{i:04}{suffix}"))
    }

    /// Whether the frame loop should hand over the next frame as a still (clears the ask).
    pub fn take_still_request(&self) -> bool {
        self.still_wanted.swap(false, Ordering::Relaxed)
    }

    /// The views whose stills were asked for and not taken yet: each with when it was
    /// asked for and whom to tell.
    pub fn take_view_stills(&self) -> Vec<ViewStill> {
        std::mem::take(&mut *self.view_stills.locked())
    }

    /// Stills asked for that wait for the next frame with a picture (the source was silent).
    pub fn put_back_view_stills(&self, waiting: Vec<ViewStill>) {
        let mut stills = self.view_stills.locked();
        // Older first, as they were asked for.
        let newer = std::mem::replace(&mut *stills, waiting);
        stills.extend(newer);
    }

    /// Writes a view's still, tagged with where it was taken, on a thread of its own and
    /// says where (or why not) to `done`.
    pub fn save_view_still(
        self: &Arc<Self>,
        (data, layout): (Vec<u8>, PlaneLayout),
        tag: Geotag,
        done: StillDone,
    ) {
        let view = tag.camera;
        let path = self.name(&format!("-cam{view}.{}", self.cfg.still_format.extension()));
        let this = self.clone();
        self.in_order(Box::new(move || {
            let written = this.write_image(&path, &data, &layout, Some(&tag));
            this.still_done(&written);
            match &written {
                Ok(()) => {
                    info!("still of camera {view}: {}", path.display());
                    this.images.fetch_add(1, Ordering::Relaxed);
                }
                Err(e) => error!("still {}: {e}", path.display()),
            }
            done(match written {
                Ok(()) => Ok((std::fs::canonicalize(&path).unwrap_or(path), tag)),
                Err(e) => Err(CaptureError::Still(Box::new(e))),
            });
        }));
    }

    /// Encodes one picture to `path` in the configured format, with the EXIF and XMP of
    /// `tag` where given.
    fn write_image(
        &self,
        path: &std::path::Path,
        data: &[u8],
        layout: &PlaneLayout,
        tag: Option<&Geotag>,
    ) -> Result<(), StillError> {
        let img = crate::frame::yuv::decode(data, layout)?;
        let format = match self.cfg.still_format {
            StillFormat::Jpeg => image::ImageFormat::Jpeg,
            StillFormat::Png => image::ImageFormat::Png,
        };
        let mut encoded = std::io::Cursor::new(Vec::new());
        img.write_to(&mut encoded, format)?;
        let mut bytes = encoded.into_inner();
        if let Some(tag) = tag {
            bytes = super::geotag::tagged(bytes, format == image::ImageFormat::Png, tag)?;
        }
        std::fs::write(path, bytes).map_err(|source| StillError::Write {
            path: path.to_path_buf(),
            source,
        })
    }

    /// Whether the encoder should send a key frame now (clears the ask).
    pub fn take_key_request(&self) -> bool {
        self.key_wanted.swap(false, Ordering::Relaxed)
    }

    /// Writes a still on the stills' writer, so the frame loop never waits on the disk.
    pub fn save_still(self: &Arc<Self>, still: Still) {
        let base = self.name("");
        let this = self.clone();
        self.in_order(Box::new(move || {
            let this = &*this;
            let ext = this.cfg.still_format.extension();
            let mut files = vec![(base.with_extension(ext), still.output)];
            if let Some(raw) = still.raw {
                let name = format!("{}-fisheye.{ext}", base.display());
                files.push((PathBuf::from(name), raw));
            }
            for (path, (data, layout)) in files {
                let written = this.write_image(&path, &data, &layout, None);
                this.still_done(&written);
                match written {
                    Ok(()) => info!("still: {}", path.display()),
                    Err(e) => {
                        error!("still {}: {e}", path.display());
                        return;
                    }
                }
            }
            this.images.fetch_add(1, Ordering::Relaxed);
        }));
    }

    /// Feeds the recording, if one runs (called for every access unit).
    pub fn on_access_unit(&self, au: &AccessUnit) {
        let mut recorder = self.recorder.locked();
        recording::feed(&mut recorder, au, &self.disk(), &self.report);
    }

    /// Ends the running recordings cleanly (shutdown).
    pub fn finish(&self) {
        let _ = Capturer::record(self, false);
        for i in 0..MAX_CAMERAS {
            let _ = self.record_view(i, false);
        }
    }

    /// Whether view `i`'s own stream is being recorded (its encoder must run).
    pub fn view_recording(&self, i: usize) -> bool {
        self.view_recorders()[i].is_some()
    }

    /// Whether view `i`'s encoder should send a key frame now (a recording starts).
    pub fn take_view_key_request(&self, i: usize) -> bool {
        self.view_key_wanted[i].swap(false, Ordering::Relaxed)
    }

    /// Feeds view `i`'s recording, if one runs (each of its stream's access units).
    pub fn on_view_access_unit(&self, i: usize, au: &AccessUnit) {
        let mut recorders = self.view_recorders();
        recording::feed(&mut recorders[i], au, &self.disk(), &self.report);
    }

    fn view_recorders(&self) -> std::sync::MutexGuard<'_, [Option<Running>; MAX_CAMERAS]> {
        self.view_recorders.locked()
    }

    /// Starts (`on`) or ends the recording of view `i`'s own stream.
    pub fn record_view(&self, i: usize, on: bool) -> Result<(), CaptureError> {
        let mut recorders = self.view_recorders();
        match (on, recorders[i].is_some()) {
            // Finished outside the lock: the stream's units go on meanwhile (up to 5 s).
            (false, _) => {
                let ended = recorders[i].take();
                drop(recorders);
                if let Some(r) = ended {
                    r.finish();
                }
            }
            (true, true) => {}
            (true, false) => {
                let name = self.name(&format!("-cam{i}{}", self.cfg.container.extension()));
                recorders[i] = Some(self.start(&name, format!("camera {i}'s recording"))?);
                self.view_key_wanted[i].store(true, Ordering::Relaxed);
            }
        }
        Ok(())
    }

    /// Starts a recording to `path`, when the disk has room: any failure reported before is
    /// over.
    fn start(&self, path: &std::path::Path, what: String) -> Result<Running, CaptureError> {
        self.ready()?;
        let r = Recorder::start(path, self.cfg.codec, self.cfg.container)
            .map_err(|e| CaptureError::Recorder(Box::new(e)))?;
        info!("{what} to {}", r.path().display());
        self.report.set_capture_failure(None);
        self.videos.fetch_add(1, Ordering::Relaxed);
        Ok(Running::new(r, what))
    }
}

impl ViewShooter for Capture {
    fn record(&self, view: usize, on: bool) -> Result<(), CaptureError> {
        self.record_view(view, on)
    }

    fn recording(&self, view: usize) -> bool {
        self.view_recording(view)
    }

    fn shoot(&self, view: usize, done: StillDone) -> Result<(), CaptureError> {
        self.ready()?;
        self.view_stills.locked().push((view, Instant::now(), done));
        Ok(())
    }

    fn dir(&self) -> &std::path::Path {
        &self.cfg.dir
    }

    fn format(&self) -> std::io::Result<usize> {
        // Both recorders' locks held while removing: no recording starts or ends meanwhile.
        let composed = self.recorder.locked();
        let views = self.view_recorders();
        let keep: Vec<&std::path::Path> = composed
            .iter()
            .chain(views.iter().flatten())
            .map(|r| r.path())
            .collect();
        crate::state::capture::remove_captures(&self.cfg.dir, &keep)
    }
}

impl Capturer for Capture {
    fn still(&self) -> Result<(), CaptureError> {
        self.ready()?;
        self.still_wanted.store(true, Ordering::Relaxed);
        Ok(())
    }

    fn record(&self, on: bool) -> Result<(), CaptureError> {
        let mut recorder = self.recorder.locked();
        match (on, recorder.is_some()) {
            // Finished outside the lock, as before: the encoder's units go on meanwhile.
            (false, _) => {
                let ended = recorder.take();
                drop(recorder);
                if let Some(r) = ended {
                    r.finish();
                }
            }
            (true, true) => {}
            (true, false) => {
                let name = self.name(self.cfg.container.extension());
                *recorder = Some(self.start(&name, "the recording".into())?);
                self.key_wanted.store(true, Ordering::Relaxed);
            }
        }
        Ok(())
    }

    fn status(&self) -> CaptureStatus {
        CaptureStatus {
            recording: self.recorder.locked().is_some(),
            images: self.images.load(Ordering::Relaxed),
            videos: self.videos.load(Ordering::Relaxed),
        }
    }
}
