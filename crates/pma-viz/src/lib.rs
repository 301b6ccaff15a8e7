//! Rerun logging of pma-exo runs. The only crate that depends on `rerun`; it knows nothing
//! of the simulation: callers register scalar series, link shapes and muscle lines, then
//! push plain [`Frame`]s, so the bench, the leg and later the rig share one layer.
//!
//! Every frame (scalars, link poses, muscle lines) is buffered column-wise and sent in
//! chunks of [`CHUNK_LEN`] frames (bounded memory, one `send_columns` per entity and
//! chunk). A `--rerun-hz` below the control rate decimates frames before anything is
//! buffered.
//!
//! The matching viewer: `pip install rerun-sdk==0.36.3`.
#![warn(missing_docs)]

use rerun::{RecordingStream, RecordingStreamBuilder, TimeColumn};
use std::path::PathBuf;
use std::str::FromStr;
use thiserror::Error;

pub use rerun::sink::MemorySinkStorage;

/// Version of the `rerun` crate (and of the viewer to install).
pub const RERUN_VERSION: &str = "0.36.3";

/// Tableau's ten colours, for the series of one group.
pub const PALETTE: [[u8; 3]; 10] = [
    [31, 119, 180],
    [255, 127, 14],
    [44, 160, 44],
    [214, 39, 40],
    [148, 103, 189],
    [140, 86, 75],
    [227, 119, 194],
    [127, 127, 127],
    [188, 189, 34],
    [23, 190, 207],
];

/// Samples per scalar chunk sent to Rerun.
pub const CHUNK_LEN: usize = 256;

/// Default viewer address of `connect`.
pub const DEFAULT_URL: &str = "rerun+http://127.0.0.1:9876/proxy";

/// Where a run's recording goes.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Sink {
    /// No logging.
    Off,
    /// Start a viewer (`rerun` on `PATH`).
    Spawn,
    /// Stream to a running viewer (default URL if `None`).
    Connect(Option<String>),
    /// Write a `.rrd` file.
    Save(PathBuf),
}

/// Visualisation errors.
#[derive(Debug, Error)]
pub enum VizError {
    /// `--rerun` could not be parsed.
    #[error(
        "unknown --rerun mode `{0}` (expected off, spawn, connect, connect=URL or save=PATH.rrd)"
    )]
    BadMode(String),
    /// The viewer could not be started.
    #[error("cannot spawn the Rerun viewer ({0}); install it with `pip install rerun-sdk=={RERUN_VERSION}`")]
    Spawn(String),
    /// No viewer listens at the address.
    #[error("no Rerun viewer reachable at {url} ({reason}); start one with `rerun` or use --rerun save=PATH.rrd")]
    Connect {
        /// Address.
        url: String,
        /// Why.
        reason: String,
    },
    /// The viewer `--rerun spawn` started exited before it could show anything.
    #[error("the Rerun viewer exited at start ({status}): {message}; without a display, use --rerun save=PATH.rrd and open the file elsewhere")]
    ViewerExited {
        /// Exit status.
        status: String,
        /// The first line it printed on stderr.
        message: String,
    },
    /// The viewer went away during the run.
    #[error("the Rerun viewer at {url} is gone (closed or crashed during the run): the recording is incomplete")]
    ViewerGone {
        /// Address.
        url: String,
    },
    /// A viewer did not take the end of the recording in time (the run itself finished).
    #[error("the Rerun viewer did not take the end of the recording within {seconds} s; it may be incomplete")]
    FlushTimeout {
        /// The wait (s).
        seconds: u64,
    },
    /// Any other Rerun error.
    #[error("rerun: {0}")]
    Rerun(String),
}

/// How long [`Viz::finish`] waits for a viewer (`spawn`, `connect`) to take what is left;
/// a file or memory sink is always waited for.
pub const VIEWER_FLUSH_TIMEOUT_S: u64 = 10;

impl FromStr for Sink {
    type Err = VizError;
    fn from_str(s: &str) -> Result<Self, VizError> {
        match s {
            "off" => Ok(Sink::Off),
            "spawn" => Ok(Sink::Spawn),
            "connect" => Ok(Sink::Connect(None)),
            _ => {
                if let Some(url) = s.strip_prefix("connect=").filter(|u| !u.is_empty()) {
                    Ok(Sink::Connect(Some(url.to_owned())))
                } else if let Some(p) = s.strip_prefix("save=").filter(|p| !p.is_empty()) {
                    Ok(Sink::Save(PathBuf::from(p)))
                } else {
                    Err(VizError::BadMode(s.to_owned()))
                }
            }
        }
    }
}

fn rr<E: std::fmt::Display>(e: E) -> VizError {
    VizError::Rerun(e.to_string())
}

/// `host:port` of a viewer URL such as `rerun+http://127.0.0.1:9876/proxy`.
fn host_port(url: &str) -> Option<String> {
    let rest = url.split("://").nth(1)?;
    let hp = rest.split('/').next()?;
    Some(if hp.contains(':') {
        hp.to_owned()
    } else {
        format!("{hp}:9876")
    })
}

/// Fails fast (1 s) when nothing listens at the viewer's address, instead of buffering
/// a whole run for a viewer that is not there.
fn check_reachable(url: &str) -> Result<(), VizError> {
    use std::net::ToSocketAddrs;
    let err = |reason: String| VizError::Connect {
        url: url.to_owned(),
        reason,
    };
    let hp = host_port(url).ok_or_else(|| err("cannot read host:port from it".into()))?;
    let addr = hp
        .to_socket_addrs()
        .map_err(|e| err(e.to_string()))?
        .next()
        .ok_or_else(|| err("no address".into()))?;
    std::net::TcpStream::connect_timeout(&addr, std::time::Duration::from_secs(1))
        .map(|_| ())
        .map_err(|e| err(e.to_string()))
}

/// The port of the viewer `spawn` starts (Rerun's default).
const VIEWER_PORT: u16 = 9876;

/// How long a spawned viewer gets to listen.
const VIEWER_START_S: u64 = 10;

/// Starts `rerun` (unless a viewer already listens on `port`) and waits until it listens;
/// a viewer that exits first (no display, say) is an error with its own message. Rerun's
/// `spawn` would forget the process and let the run stream into nothing.
fn spawn_viewer(port: u16) -> Result<(), VizError> {
    use std::net::{Ipv4Addr, SocketAddr, TcpStream};
    use std::time::{Duration, Instant};
    let addr = SocketAddr::from((Ipv4Addr::LOCALHOST, port));
    let listening = || TcpStream::connect_timeout(&addr, Duration::from_millis(200)).is_ok();
    if listening() {
        return Ok(());
    }
    let log = std::env::temp_dir().join(format!("pma-exo-rerun-viewer-{}.log", std::process::id()));
    let stderr = std::fs::File::create(&log)
        .map_err(|e| VizError::Spawn(format!("{}: {e}", log.display())))?;
    let mut child = std::process::Command::new("rerun")
        .args([
            format!("--port={port}"),
            "--memory-limit=75%".into(),
            "--expect-data-soon".into(),
        ])
        .stdin(std::process::Stdio::null())
        .stdout(std::process::Stdio::null())
        .stderr(stderr)
        .spawn()
        .map_err(|e| {
            VizError::Spawn(if e.kind() == std::io::ErrorKind::NotFound {
                "`rerun` is not on PATH".into()
            } else {
                e.to_string()
            })
        })?;
    let start = Instant::now();
    while start.elapsed() < Duration::from_secs(VIEWER_START_S) {
        if listening() {
            return Ok(());
        }
        // The launcher may fork the viewer and exit 0: only a failure is final.
        if let Ok(Some(status)) = child.try_wait() {
            if !status.success() {
                let text = std::fs::read_to_string(&log).unwrap_or_default();
                let message = text
                    .lines()
                    .map(str::trim)
                    .find(|l| !l.is_empty())
                    .unwrap_or("no message")
                    .to_owned();
                let _ = std::fs::remove_file(&log);
                return Err(VizError::ViewerExited {
                    status: status.to_string(),
                    message,
                });
            }
        }
        std::thread::sleep(Duration::from_millis(100));
    }
    Err(VizError::Spawn(format!(
        "the viewer did not listen on port {port} within {VIEWER_START_S} s"
    )))
}

/// A link's drawable shape, in the link's frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Shape {
    /// Cylinder along the link's Z axis.
    Cylinder {
        /// Centre (m).
        center: [f32; 3],
        /// Radius (m).
        radius: f32,
        /// Length (m).
        length: f32,
    },
    /// Box.
    Box {
        /// Centre (m).
        center: [f32; 3],
        /// Half sizes (m).
        half_size: [f32; 3],
    },
}

/// Buffered columns of one registered entity, sent every [`CHUNK_LEN`] frames.
#[derive(Debug)]
struct Columns<T> {
    path: String,
    rows: Vec<T>,
}

impl<T> Columns<T> {
    fn new(path: String) -> Self {
        Self {
            path,
            rows: Vec::with_capacity(CHUNK_LEN),
        }
    }
}

/// A labelled ball drawn for a while, e.g. on a joint during an event.
#[derive(Debug, Clone, PartialEq)]
pub struct Marker {
    /// Centre in the parent entity's frame (m).
    pub position_m: [f32; 3],
    /// Radius (m).
    pub radius_m: f32,
    /// Colour.
    pub rgb: [u8; 3],
    /// Text shown beside it.
    pub label: String,
}

/// A muscle line's row: end points and colour.
type LineRow = ([[f32; 3]; 2], rerun::Color);

/// One logged instant: values in registration order.
#[derive(Debug, Clone, Copy)]
pub struct Frame<'a> {
    /// Simulated time (s), timeline `sim_time`.
    pub t_s: f64,
    /// Control period index, timeline `step`.
    pub step: i64,
    /// One value per registered series.
    pub scalars: &'a [f64],
    /// One pose per registered link: translation (m) and quaternion `[x, y, z, w]`.
    pub link_poses: &'a [([f64; 3], [f64; 4])],
    /// One segment per registered muscle line: end points (m) and pressure (Pa).
    pub muscle_lines: &'a [([f64; 3], [f64; 3], f64)],
    /// One ground reaction per foot [`Viz::ground`] registered, in its order.
    pub grounds: &'a [GroundFrame<'a>],
}

/// The ground's reaction on a foot in one frame.
#[derive(Debug, Clone, Copy)]
pub struct GroundFrame<'a> {
    /// Points where the foot touches the ground (m).
    pub contacts_m: &'a [[f64; 3]],
    /// Where the resultant acts: the centre of pressure (m).
    pub at_m: [f64; 3],
    /// The resultant force (N); drawn at [`GRF_ARROW_M_PER_N`].
    pub force_n: [f64; 3],
}

/// Length of the ground reaction's arrow per newton (m/N): 1 kN is half a metre.
pub const GRF_ARROW_M_PER_N: f64 = 5e-4;

/// Buffered rows of the ground reaction: arrows (origin, vector) and contact points.
#[derive(Debug)]
struct GroundColumns {
    arrow_path: String,
    points_path: String,
    arrows: Vec<([f32; 3], [f32; 3])>,
    points: Vec<[f32; 3]>,
    counts: Vec<usize>,
}

/// A recording stream with the registered layout.
///
/// Everything per frame (scalars, link poses, muscle lines) is buffered column-wise and
/// sent with `send_columns` once [`CHUNK_LEN`] frames are buffered: a row-wise `log` per
/// entity and frame cost more than the simulation step itself.
pub struct Viz {
    rec: RecordingStream,
    t_s: Vec<f64>,
    steps: Vec<i64>,
    series: Vec<Columns<f64>>,
    links: Vec<Columns<([f32; 3], [f32; 4])>>,
    muscles: Vec<Columns<LineRow>>,
    grounds: Vec<GroundColumns>,
    pressure_max_pa: f64,
    every: i64,
    /// `None`: wait for the sink however long it takes (file, memory).
    flush_timeout: Option<std::time::Duration>,
    /// The viewer's address, checked before the end of the recording is sent.
    viewer_url: Option<String>,
}

/// Radius of the drawn muscles (m).
const MUSCLE_RADIUS_M: f32 = 0.012;

fn f32x<const N: usize>(a: &[f64; N]) -> [f32; N] {
    a.map(|x| x as f32)
}

/// Blue (vented) to red (full pressure).
fn pressure_color(pressure_pa: f64, pressure_max_pa: f64) -> rerun::Color {
    let level = (pressure_pa / pressure_max_pa).clamp(0.0, 1.0);
    rerun::Color::from_rgb((255.0 * level) as u8, 60, (255.0 * (1.0 - level)) as u8)
}

impl Viz {
    /// Opens `sink` (`None` for [`Sink::Off`]). `rate_hz` decimates frames pushed at
    /// `period_s`; `None` logs every one.
    pub fn open(
        sink: &Sink,
        app: &'static str,
        period_s: f64,
        rate_hz: Option<f64>,
    ) -> Result<Option<Self>, VizError> {
        let builder = RecordingStreamBuilder::new(app);
        let viewer_wait = Some(std::time::Duration::from_secs(VIEWER_FLUSH_TIMEOUT_S));
        let (rec, flush_timeout) = match sink {
            Sink::Off => return Ok(None),
            Sink::Spawn => {
                spawn_viewer(VIEWER_PORT)?;
                let url = DEFAULT_URL.to_owned();
                (
                    builder.connect_grpc_opts(url.clone()).map_err(rr)?,
                    Some((viewer_wait, url)),
                )
            }
            Sink::Connect(url) => {
                let url = url.clone().unwrap_or_else(|| DEFAULT_URL.to_owned());
                check_reachable(&url)?;
                (
                    builder.connect_grpc_opts(url.clone()).map_err(rr)?,
                    Some((viewer_wait, url)),
                )
            }
            Sink::Save(path) => (builder.save(path).map_err(rr)?, None),
        };
        let mut viz = Self::with_stream(rec, period_s, rate_hz)?;
        if let Some((wait, url)) = flush_timeout {
            viz.flush_timeout = wait;
            viz.viewer_url = Some(url);
        }
        Ok(Some(viz))
    }

    /// An in-memory recording (tests): the stream and its storage.
    pub fn memory(
        app: &'static str,
        period_s: f64,
        rate_hz: Option<f64>,
    ) -> Result<(Self, MemorySinkStorage), VizError> {
        let (rec, storage) = RecordingStreamBuilder::new(app).memory().map_err(rr)?;
        Ok((Self::with_stream(rec, period_s, rate_hz)?, storage))
    }

    fn with_stream(
        rec: RecordingStream,
        period_s: f64,
        rate_hz: Option<f64>,
    ) -> Result<Self, VizError> {
        let every = match rate_hz {
            None => 1,
            Some(hz) if hz.is_finite() && hz > 0.0 => {
                ((1.0 / (hz * period_s)).round() as i64).max(1)
            }
            Some(hz) => {
                return Err(VizError::Rerun(format!(
                    "--rerun-hz must be > 0 (got {hz})"
                )))
            }
        };
        rec.log_static("world", &rerun::ViewCoordinates::RIGHT_HAND_Z_UP())
            .map_err(rr)?;
        Ok(Self {
            rec,
            t_s: Vec::with_capacity(CHUNK_LEN),
            steps: Vec::with_capacity(CHUNK_LEN),
            series: Vec::new(),
            links: Vec::new(),
            muscles: Vec::new(),
            grounds: Vec::new(),
            pressure_max_pa: 6.0e5,
            every,
            flush_timeout: None,
            viewer_url: None,
        })
    }

    /// Periods between logged frames.
    pub fn decimation(&self) -> i64 {
        self.every
    }

    /// Static text (scenario, controller, gains) at `path`.
    pub fn document(&self, path: &str, markdown: &str) -> Result<(), VizError> {
        self.rec
            .log_static(path, &rerun::TextDocument::from_markdown(markdown))
            .map_err(rr)
    }

    /// Registers a scalar series at `path` with its legend `name` (units in it) and colour.
    pub fn series(&mut self, path: &str, name: &str, rgb: [u8; 3]) -> Result<(), VizError> {
        self.rec
            .log_static(
                path,
                &rerun::SeriesLines::new()
                    .with_names([name])
                    .with_colors([rerun::Color::from_rgb(rgb[0], rgb[1], rgb[2])]),
            )
            .map_err(rr)?;
        self.series.push(Columns::new(path.to_owned()));
        Ok(())
    }

    /// Registers every channel of `schema` as a series, in order (the order of a frame's
    /// scalars), coloured by its place among its siblings.
    pub fn schema(&mut self, schema: &pma_loop::Schema) -> Result<(), VizError> {
        let mut parent = "";
        let mut k = 0;
        for c in &schema.channels {
            let here = c.path.rsplit_once('/').map_or("", |(p, _)| p);
            if here != parent {
                parent = here;
                k = 0;
            }
            self.series(&c.path, &c.doc, PALETTE[k % PALETTE.len()])?;
            k += 1;
        }
        Ok(())
    }

    /// Registers a link at `world/<name>` with its shapes (in the link frame).
    pub fn link(&mut self, name: &str, shapes: &[Shape], rgb: [u8; 3]) -> Result<(), VizError> {
        let path = format!("world/{name}");
        let color = rerun::Color::from_rgb(rgb[0], rgb[1], rgb[2]);
        for (k, s) in shapes.iter().enumerate() {
            let p = format!("{path}/geometry_{k}");
            match *s {
                Shape::Cylinder {
                    center,
                    radius,
                    length,
                } => self.rec.log_static(
                    p,
                    &rerun::Cylinders3D::from_lengths_and_radii([length], [radius])
                        .with_centers([center])
                        .with_colors([color]),
                ),
                Shape::Box { center, half_size } => self.rec.log_static(
                    p,
                    &rerun::Boxes3D::from_centers_and_half_sizes([center], [half_size])
                        .with_colors([color])
                        .with_fill_mode(rerun::FillMode::Solid),
                ),
            }
            .map_err(rr)?;
        }
        self.links.push(Columns::new(path));
        Ok(())
    }

    /// Draws a static box (a belt, a floor) at `world/<name>`.
    pub fn fixture(&self, name: &str, shape: &Shape, rgb: [u8; 3]) -> Result<(), VizError> {
        let color = rerun::Color::from_rgb(rgb[0], rgb[1], rgb[2]);
        let path = format!("world/{name}");
        match *shape {
            Shape::Box { center, half_size } => self.rec.log_static(
                path,
                &rerun::Boxes3D::from_centers_and_half_sizes([center], [half_size])
                    .with_colors([color])
                    .with_fill_mode(rerun::FillMode::Solid),
            ),
            Shape::Cylinder {
                center,
                radius,
                length,
            } => self.rec.log_static(
                path,
                &rerun::Cylinders3D::from_lengths_and_radii([length], [radius])
                    .with_centers([center])
                    .with_colors([color]),
            ),
        }
        .map_err(rr)
    }

    /// Registers a foot's ground reaction drawn at `world/<name>/grf` (an arrow at the
    /// centre of pressure) and `world/<name>/contacts` (the contact points), the next of
    /// every frame's [`Frame::grounds`].
    pub fn ground(&mut self, name: &str) -> Result<(), VizError> {
        let arrow_path = format!("world/{name}/grf");
        let points_path = format!("world/{name}/contacts");
        self.rec
            .log_static(
                arrow_path.as_str(),
                &rerun::Arrows3D::update_fields()
                    .with_colors([rerun::Color::from_rgb(40, 160, 60)])
                    .with_radii([0.008]),
            )
            .map_err(rr)?;
        self.rec
            .log_static(
                points_path.as_str(),
                &rerun::Points3D::update_fields()
                    .with_colors([rerun::Color::from_rgb(230, 120, 20)])
                    .with_radii([0.012]),
            )
            .map_err(rr)?;
        self.grounds.push(GroundColumns {
            arrow_path,
            points_path,
            arrows: Vec::with_capacity(CHUNK_LEN),
            // Two spheres a foot in most models; more only reallocates once.
            points: Vec::with_capacity(2 * CHUNK_LEN),
            counts: Vec::with_capacity(CHUNK_LEN),
        });
        Ok(())
    }

    /// Registers a muscle drawn at `world/muscles/<name>`; `pressure_max_pa` scales colour.
    pub fn muscle(&mut self, name: &str, pressure_max_pa: f64) -> Result<(), VizError> {
        let path = format!("world/muscles/{name}");
        // The radius never changes: logged once, static, instead of once per frame.
        self.rec
            .log_static(
                path.as_str(),
                &rerun::LineStrips3D::update_fields().with_radii([MUSCLE_RADIUS_M]),
            )
            .map_err(rr)?;
        self.muscles.push(Columns::new(path));
        self.pressure_max_pa = pressure_max_pa;
        Ok(())
    }

    /// Puts the stream's own clock at `t_s` and `step`, for the rows logged one at a time
    /// (events and markers; the series go by columns with their own times).
    fn at(&self, t_s: f64, step: i64) {
        self.rec.set_duration_secs("sim_time", t_s);
        self.rec.set_time_sequence("step", step);
    }

    /// A line in the text log at `path` at `t_s`, with `level` (`"INFO"`, `"WARN"` ...).
    pub fn event(
        &self,
        t_s: f64,
        step: i64,
        path: &str,
        text: &str,
        level: &str,
    ) -> Result<(), VizError> {
        self.at(t_s, step);
        self.rec
            .log(path, &rerun::TextLog::new(text).with_level(level))
            .map_err(rr)
    }

    /// Shows `marker` at `path` (in the frame of its parent) from `t_s` until
    /// [`Self::clear`].
    pub fn marker(&self, t_s: f64, step: i64, path: &str, marker: &Marker) -> Result<(), VizError> {
        self.at(t_s, step);
        let [r, g, b] = marker.rgb;
        self.rec
            .log(
                path,
                &rerun::Points3D::new([marker.position_m])
                    .with_radii([marker.radius_m])
                    .with_colors([rerun::Color::from_rgb(r, g, b)])
                    .with_labels([marker.label.as_str()])
                    .with_show_labels(true),
            )
            .map_err(rr)
    }

    /// A red cross named `name` at `(t_s, value)` in the time-series plot of `path`'s
    /// parent: an instant (a fault, a vent) marked on the curves it interrupts.
    pub fn series_marker(
        &self,
        t_s: f64,
        step: i64,
        path: &str,
        name: &str,
        value: f64,
    ) -> Result<(), VizError> {
        self.at(t_s, step);
        self.rec
            .log(
                path,
                &[
                    &rerun::SeriesPoints::new()
                        .with_names([name])
                        .with_colors([rerun::Color::from_rgb(214, 39, 40)])
                        .with_markers([rerun::components::MarkerShape::Cross])
                        .with_marker_sizes([8.0]) as &dyn rerun::AsComponents,
                    &rerun::Scalars::single(value),
                ],
            )
            .map_err(rr)
    }

    /// Removes what `path` shows from `t_s` on.
    pub fn clear(&self, t_s: f64, step: i64, path: &str) -> Result<(), VizError> {
        self.at(t_s, step);
        self.rec.log(path, &rerun::Clear::flat()).map_err(rr)
    }

    /// Buffers a frame if it falls on the decimation grid; sends the buffers when they
    /// hold [`CHUNK_LEN`] frames. Allocation-free between sends.
    pub fn push(&mut self, f: &Frame) -> Result<(), VizError> {
        if f.step % self.every != 0 {
            return Ok(());
        }
        self.t_s.push(f.t_s);
        self.steps.push(f.step);
        for (s, v) in self.series.iter_mut().zip(f.scalars) {
            s.rows.push(*v);
        }
        for (l, (t, q)) in self.links.iter_mut().zip(f.link_poses) {
            l.rows.push((f32x(t), f32x(q)));
        }
        for (m, (a, b, p)) in self.muscles.iter_mut().zip(f.muscle_lines) {
            m.rows
                .push(([f32x(a), f32x(b)], pressure_color(*p, self.pressure_max_pa)));
        }
        for (g, frame) in self.grounds.iter_mut().zip(f.grounds) {
            let vector = frame.force_n.map(|v| v * GRF_ARROW_M_PER_N);
            // Out of contact the arrow has no origin: drawn as nothing at the origin.
            let origin = if frame.at_m.iter().all(|v| v.is_finite()) {
                frame.at_m
            } else {
                [0.0; 3]
            };
            g.arrows.push((f32x(&origin), f32x(&vector)));
            g.points.extend(frame.contacts_m.iter().map(f32x));
            g.counts.push(frame.contacts_m.len());
        }
        if self.t_s.len() >= CHUNK_LEN {
            self.flush()?;
        }
        Ok(())
    }

    fn time_columns(&self) -> [TimeColumn; 2] {
        [
            TimeColumn::new_duration_secs("sim_time", self.t_s.iter().copied()),
            TimeColumn::new_sequence("step", self.steps.iter().copied()),
        ]
    }

    /// Sends every buffered frame, one `send_columns` per entity, and empties the buffers.
    fn flush(&mut self) -> Result<(), VizError> {
        if self.t_s.is_empty() {
            return Ok(());
        }
        let times = self.time_columns();
        let send = |path: &str, cols: Vec<rerun::SerializedComponentColumn>| {
            self.rec.send_columns(path, times.clone(), cols).map_err(rr)
        };
        for s in &mut self.series {
            send(
                &s.path,
                rerun::Scalars::new(s.rows.drain(..))
                    .columns_of_unit_batches()
                    .map_err(rr)?
                    .collect(),
            )?;
        }
        for l in &mut self.links {
            send(
                &l.path,
                rerun::Transform3D::update_fields()
                    .with_many_translation(l.rows.iter().map(|r| r.0))
                    .with_many_quaternion(l.rows.iter().map(|r| rerun::Quaternion::from_xyzw(r.1)))
                    .columns_of_unit_batches()
                    .map_err(rr)?
                    .collect(),
            )?;
            l.rows.clear();
        }
        for m in &mut self.muscles {
            send(
                &m.path,
                rerun::LineStrips3D::update_fields()
                    .with_strips(m.rows.iter().map(|r| r.0))
                    .with_colors(m.rows.iter().map(|r| r.1))
                    .columns_of_unit_batches()
                    .map_err(rr)?
                    .collect(),
            )?;
            m.rows.clear();
        }
        for g in &mut self.grounds {
            if g.arrows.len() == self.t_s.len() {
                send(
                    &g.arrow_path,
                    rerun::Arrows3D::update_fields()
                        .with_origins(g.arrows.iter().map(|r| r.0))
                        .with_vectors(g.arrows.iter().map(|r| r.1))
                        .columns_of_unit_batches()
                        .map_err(rr)?
                        .collect(),
                )?;
                send(
                    &g.points_path,
                    rerun::Points3D::update_fields()
                        .with_positions(g.points.iter().copied())
                        .columns(g.counts.iter().copied())
                        .map_err(rr)?
                        .collect(),
                )?;
            }
            g.arrows.clear();
            g.points.clear();
            g.counts.clear();
        }
        self.t_s.clear();
        self.steps.clear();
        Ok(())
    }

    /// Sends what is buffered and waits for the sink: a file or memory sink until it has
    /// everything, a viewer at most [`VIEWER_FLUSH_TIMEOUT_S`] (then
    /// [`VizError::FlushTimeout`], and the stream is abandoned rather than dropped), so
    /// that a stuck viewer never holds the run.
    pub fn finish(mut self) -> Result<(), VizError> {
        if let Some(url) = &self.viewer_url {
            if check_reachable(url).is_err() {
                // Nobody to send the rest to: say so now instead of waiting for a flush.
                let url = url.clone();
                std::mem::forget(self.rec);
                return Err(VizError::ViewerGone { url });
            }
        }
        self.flush()?;
        match self.flush_timeout {
            None => self.rec.flush_blocking().map_err(rr),
            Some(t) => match self.rec.flush_with_timeout(t) {
                Err(rerun::sink::SinkFlushError::Timeout) => {
                    // Dropping the stream would wait for the viewer again, without limit
                    // (the gRPC client flushes forever on drop): abandon it instead, its
                    // thread ends with the process or when the viewer catches up.
                    std::mem::forget(self.rec);
                    Err(VizError::FlushTimeout {
                        seconds: t.as_secs(),
                    })
                }
                other => other.map_err(rr),
            },
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn modes_parse() {
        assert_eq!("off".parse::<Sink>().unwrap(), Sink::Off);
        assert_eq!("spawn".parse::<Sink>().unwrap(), Sink::Spawn);
        assert_eq!("connect".parse::<Sink>().unwrap(), Sink::Connect(None));
        assert_eq!(
            "connect=rerun+http://10.0.0.1:9876/proxy"
                .parse::<Sink>()
                .unwrap(),
            Sink::Connect(Some("rerun+http://10.0.0.1:9876/proxy".into()))
        );
        assert_eq!(
            "save=/tmp/x.rrd".parse::<Sink>().unwrap(),
            Sink::Save("/tmp/x.rrd".into())
        );
        assert!("save=".parse::<Sink>().is_err() && "viewer".parse::<Sink>().is_err());
        assert_eq!(host_port(DEFAULT_URL).as_deref(), Some("127.0.0.1:9876"));
    }

    #[test]
    fn connecting_to_no_viewer_fails_fast() {
        let t = std::time::Instant::now();
        let e = Viz::open(
            &Sink::Connect(Some("rerun+http://127.0.0.1:1/proxy".into())),
            "t",
            1e-3,
            None,
        )
        .err()
        .expect("no viewer on port 1");
        assert!(e.to_string().contains("127.0.0.1:1"), "{e}");
        assert!(t.elapsed().as_secs_f64() < 5.0);
    }
}
