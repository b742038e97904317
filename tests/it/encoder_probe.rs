//! An encoder that hangs as it starts is abandoned after its deadline and the next takes
//! over: a deliberately blocking element (registered in this process, its state change from
//! NULL to READY never returning until the test lets it go, as a hardware encoder's driver
//! opening a device it lacks does) is tried first, x264 second. The stream that comes out
//! is x264's; the next encoder started does not try the hung one again.

use digiview::frame::{PixelFormat, PlaneLayout};
use digiview::stream::encoder::AccessUnit;
use digiview::stream::probe::START_DEADLINE;
use digiview::stream::{Encoder, EncoderConfig};
use gstreamer as gst;
use gstreamer::glib;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, mpsc};
use std::time::{Duration, Instant};

/// Lets the blocked state change go once the test is done.
static RELEASE: AtomicBool = AtomicBool::new(false);

mod blocking {
    use super::RELEASE;
    use gstreamer as gst;
    use gstreamer::glib;
    use gstreamer::prelude::*;
    use gstreamer::subclass::prelude::*;
    use std::sync::LazyLock;
    use std::sync::atomic::Ordering;

    #[derive(Default)]
    pub struct Imp;

    #[glib::object_subclass]
    impl ObjectSubclass for Imp {
        const NAME: &'static str = "DigiviewTestBlockingEncoder";
        type Type = Blocking;
        type ParentType = gst::Element;
    }

    impl ObjectImpl for Imp {
        fn constructed(&self) {
            self.parent_constructed();
            let element = self.obj();
            for template in Self::pad_templates() {
                let pad = gst::Pad::from_template(template);
                element.add_pad(&pad).expect("a fresh pad");
            }
        }
    }

    impl GstObjectImpl for Imp {}

    impl ElementImpl for Imp {
        fn metadata() -> Option<&'static gst::subclass::ElementMetadata> {
            static META: LazyLock<gst::subclass::ElementMetadata> = LazyLock::new(|| {
                gst::subclass::ElementMetadata::new(
                    "Blocking encoder",
                    "Codec/Encoder/Video",
                    "Hangs in its first state change, as a driver without its device can",
                    "DigiView tests",
                )
            });
            Some(&META)
        }

        fn pad_templates() -> &'static [gst::PadTemplate] {
            static PADS: LazyLock<Vec<gst::PadTemplate>> = LazyLock::new(|| {
                let any = gst::Caps::new_any();
                let pad = |name, direction| {
                    gst::PadTemplate::new(name, direction, gst::PadPresence::Always, &any)
                        .expect("a pad template")
                };
                vec![
                    pad("sink", gst::PadDirection::Sink),
                    pad("src", gst::PadDirection::Src),
                ]
            });
            PADS.as_ref()
        }

        fn change_state(
            &self,
            transition: gst::StateChange,
        ) -> Result<gst::StateChangeSuccess, gst::StateChangeError> {
            if transition == gst::StateChange::NullToReady {
                while !RELEASE.load(Ordering::Relaxed) {
                    std::thread::sleep(std::time::Duration::from_millis(20));
                }
            }
            self.parent_change_state(transition)
        }
    }

    glib::wrapper! {
        pub struct Blocking(ObjectSubclass<Imp>) @extends gst::Element, gst::Object;
    }
}

#[test]
fn an_encoder_that_hangs_as_it_starts_is_abandoned_and_x264_takes_over() {
    digiview::stream::init().unwrap();
    gst::Element::register(
        None,
        "digiviewblockingenc",
        gst::Rank::NONE,
        <blocking::Blocking as glib::prelude::StaticType>::static_type(),
    )
    .unwrap();
    let units: Arc<Mutex<Vec<AccessUnit>>> = Arc::default();
    let kept = units.clone();
    let names = ["digiviewblockingenc".to_string(), "x264enc".to_string()];
    let (tx, rx) = mpsc::channel();
    let started = Instant::now();
    std::thread::spawn(move || {
        let cfg = EncoderConfig::default();
        let sink = move |au: AccessUnit| kept.lock().unwrap().push(au);
        let _ = tx.send(Encoder::first_to_start(&names, &cfg, 30, sink));
    });
    // The deadline, and room for x264 to start on a busy machine; never forever.
    let encoder = rx.recv_timeout(START_DEADLINE + Duration::from_secs(30));
    let waited = started.elapsed();
    RELEASE.store(true, Ordering::Relaxed);
    let mut encoder = encoder
        .expect("the encoders' start returned")
        .expect("x264 took over");
    assert_eq!(encoder.name(), "x264enc");
    assert!(waited >= START_DEADLINE, "the hung encoder was waited for");
    // A grey frame in, an access unit out: the stream that comes out is x264's.
    let layout = PlaneLayout::tight(PixelFormat::I420, 320, 240).unwrap();
    let until = Instant::now() + Duration::from_secs(30);
    for n in 0.. {
        if !units.lock().unwrap().is_empty() {
            break;
        }
        assert!(Instant::now() < until, "x264 put out nothing");
        let pts = Duration::from_millis(33 * n);
        encoder
            .push(vec![128; layout.size as usize], &layout, pts, 30)
            .unwrap();
        std::thread::sleep(Duration::from_millis(33));
    }
    assert!(
        units.lock().unwrap()[0].key,
        "the first unit is a key frame"
    );
    // The next encoder (a view's, a new watcher's) does not wait for it again.
    let names = ["digiviewblockingenc".to_string(), "x264enc".to_string()];
    let again = Instant::now();
    let next = Encoder::first_to_start(&names, &EncoderConfig::default(), 30, |_| {});
    assert_eq!(next.expect("x264 again").name(), "x264enc");
    assert!(
        again.elapsed() < START_DEADLINE,
        "the hung encoder was tried again"
    );
}
