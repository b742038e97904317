//! The assembly's adapters: each service reaches another only through a small trait or hook
//! the reaching side owns, and these give it the other's. The control protocol's AUTOPILOT
//! reads the MAVLink link's status; the HTTP server shows the video head's figures and preview
//! and serves the MAVLink cameras' definition file; the demo's flight goes out as a simulated
//! autopilot on the MAVLink link.

use crate::autopilot::sim::SimAutopilot;
use crate::autopilot::{Endpoint, LinkStatus, MavlinkConfig};
use crate::cameras::Cameras;
use crate::cameras::thermal::{Point, ThermalReader};
use crate::control::AutopilotStatus;
use crate::head::{DemoAutopilot, Head};
use crate::http::NotStarted;
use crate::protocol::params::Autopilot;
use crate::stream::Preview;
use std::sync::Arc;
use tracing::info;

struct Link(Arc<LinkStatus>);

impl AutopilotStatus for Link {
    fn param(&self) -> Autopilot {
        self.0.param()
    }
}

/// The link's status as the control protocol's AUTOPILOT reads it.
pub(super) fn autopilot_status(status: Arc<LinkStatus>) -> Arc<dyn AutopilotStatus> {
    Arc::new(Link(status))
}

struct Video(Arc<Head>);

impl crate::http::Video for Video {
    fn status(&self) -> serde_json::Value {
        let mut status = serde_json::to_value(self.0.health()).unwrap_or_default();
        if let (Some(sensor), Some(map)) = (self.0.thermal(), status.as_object_mut()) {
            map.insert("thermal".into(), sensor.status());
        }
        status
    }
    fn preview(&self) -> Arc<Preview> {
        self.0.preview()
    }
    fn estimate_readout(&self, seconds: f64) -> Result<serde_json::Value, NotStarted> {
        use crate::head::readout_probe::StartError;
        match self.0.readout_probe().start(seconds) {
            Ok(status) => Ok(serde_json::to_value(status).unwrap_or_default()),
            Err(e @ StartError::Seconds(_)) => Err(NotStarted::Bad(e.to_string())),
            Err(e @ StartError::Busy(_)) => Err(NotStarted::Busy(e.to_string())),
        }
    }
    fn readout_estimate(&self) -> serde_json::Value {
        serde_json::to_value(self.0.readout_probe().status()).unwrap_or_default()
    }
    fn thermal(
        &self,
        camera: usize,
        spot: Option<(f64, f64)>,
    ) -> Result<serde_json::Value, crate::http::thermal::Refused> {
        use crate::head::thermal::ThermalAsk;
        use crate::http::thermal::Refused;
        let spot = spot.map(|(x, y)| glam::DVec2::new(x, y));
        match self.0.thermal_in_view(camera, spot) {
            Ok(v) => Ok(serde_json::to_value(v).unwrap_or_default()),
            Err(e @ ThermalAsk::NoSensor) => Err(Refused::NoSensor(e.to_string())),
            Err(e @ ThermalAsk::NoFrame) => Err(Refused::NoFrame(e.to_string())),
            Err(e) => Err(Refused::Bad(e.to_string())),
        }
    }
}

struct Thermal(Arc<Head>);

impl crate::cameras::thermal::ThermalReader for Thermal {
    fn range(&self, camera: usize) -> Result<(Option<Point>, Option<Point>), String> {
        let v = self
            .0
            .thermal_in_view(camera, None)
            .map_err(|e| e.to_string())?;
        let (w, h) = (v.width as f64, v.height as f64);
        let point = |s: crate::thermal::Spot| Point {
            kelvin: s.kelvin,
            x: s.x / w,
            y: s.y / h,
        };
        Ok((v.hottest.map(point), v.coldest.map(point)))
    }

    fn hfov(&self) -> f64 {
        self.0.thermal().map_or(0.0, |s| s.lens.hfov())
    }
}

/// The head's thermal sensor as the MAVLink cameras read it, where it has one.
pub(super) fn thermal_reader(head: &Arc<Head>) -> Option<Arc<dyn ThermalReader>> {
    head.thermal()?;
    Some(Arc::new(Thermal(head.clone())))
}

/// The video head as the HTTP server sees it.
pub(super) fn video(head: Arc<Head>) -> Arc<dyn crate::http::Video> {
    Arc::new(Video(head))
}

/// The cameras' definition file, as the HTTP server serves it.
pub(super) fn camera_definition(cameras: Arc<Cameras>) -> Arc<dyn Fn() -> String + Send + Sync> {
    Arc::new(move || cameras.definition().0)
}

/// Where the link listens on a UDP port of this machine, the demo's flight is sent to it as an
/// autopilot's would be (at 100 Hz at least), so everything downstream of the link runs on the
/// demo too, until a real autopilot is heard there. (A TCP link serves one peer, which the
/// demo would hold: there the demo's flight goes to the telemetry, which gives way to an
/// autopilot's.)
pub(super) fn demo_autopilot(cfg: &MavlinkConfig, link: Arc<LinkStatus>) -> Option<DemoAutopilot> {
    let port = cfg.endpoint.parse::<Endpoint>().ok()?.loopback_udp_port()?;
    let rate = cfg.attitude_hz.max(100.0);
    Some(Box::new(move |flight, start| {
        info!("source: the demo's flight is a simulated autopilot sending to udp port {port}");
        Box::new(SimAutopilot::demo(
            port,
            flight.clone(),
            (start, rate),
            link.clone(),
        ))
    }))
}
