//! A haptic stylus through PLUS, end to end on loopback: a fake PlusServer (a
//! TcpListener speaking OpenIGTLink with the crate's own codec, header version
//! 2 as PlusServer sends, with its keep-alive STATUS messages) streams the
//! stylus pose (`StylusToBase`) and its buttons (`ButtonsToBase`); fissure's
//! client link reads them and the scene's mapping moves the blade by scale,
//! frame and clutch; the force goes back as the TRANSFORM a PLUS
//! `OpenIGTLinkTracker` (a client of fissure's server) turns into the
//! OpenHaptics device's `Force` tool, with the right translation, clamp and
//! rate; the PlusServer restarts and the link comes back without the blade
//! jumping. The endpoint is built from the scenario as the window builds it
//! (`fissure::app::devices::igtl_config`). And the shipped PLUS configuration
//! (`assets/devices/PlusDeviceSet_fissure_Touch.xml`) names the transforms,
//! ports and rate the shipped scene (`config/sylvian_touch.ron`) uses.

use fissure::app::devices::igtl_config;
use fissure::input::igtl::IgtlServer;
use fissure::input::igtl_codec::{HEADER_SIZE, RawMessage, crc64, decode_body_raw, decode_header, decode_sensor_body, encode_transform};
use fissure::input::igtl_link::Backoff;
use fissure::math::{Matrix3, Vec3};
use fissure::scenario::Scenario;
use std::io::{Read, Write};
use std::net::{SocketAddr, TcpListener, TcpStream};
use std::path::Path;
use std::time::{Duration, Instant};

fn wait_until(mut done: impl FnMut() -> bool, what: &str) {
    let start = Instant::now();
    while !done() {
        assert!(start.elapsed() < Duration::from_secs(20), "timed out waiting for {what}");
        std::thread::sleep(Duration::from_millis(2));
    }
}

/// A message with the given header version (2 puts the 12-byte extended
/// header before the content and a metadata block after it, as PlusServer does).
fn message(version: u16, message_type: &str, device: &str, timestamp_s: f64, content: &[u8]) -> Vec<u8> {
    let mut body = Vec::new();
    if version == 2 {
        let (meta_header, meta) = ([0u8, 1, 0, 6, 0, 3, 0, 0, 0, 2], b"StatusOK");
        body.extend_from_slice(&12u16.to_be_bytes());
        body.extend_from_slice(&(meta_header.len() as u16).to_be_bytes());
        body.extend_from_slice(&(meta.len() as u32).to_be_bytes());
        body.extend_from_slice(&1u32.to_be_bytes());
        body.extend_from_slice(content);
        body.extend_from_slice(&meta_header);
        body.extend_from_slice(meta);
    } else {
        body.extend_from_slice(content);
    }
    let mut out = Vec::new();
    out.extend_from_slice(&version.to_be_bytes());
    let mut name = [0u8; 12];
    name[..message_type.len()].copy_from_slice(message_type.as_bytes());
    out.extend_from_slice(&name);
    let mut dev = [0u8; 20];
    dev[..device.len()].copy_from_slice(device.as_bytes());
    out.extend_from_slice(&dev);
    out.extend_from_slice(&(timestamp_s.floor() as u32).to_be_bytes());
    out.extend_from_slice(&(((timestamp_s - timestamp_s.floor()) * 4_294_967_296.0) as u32).to_be_bytes());
    out.extend_from_slice(&(body.len() as u64).to_be_bytes());
    out.extend_from_slice(&crc64(&body).to_be_bytes());
    out.extend_from_slice(&body);
    out
}

/// PlusServer's TRANSFORM of a tool: header v2, the content as the codec writes it.
fn plus_transform(device: &str, timestamp_s: f64, matrix: &Matrix3<f64>, translation: Vec3) -> Vec<u8> {
    let v1 = encode_transform(device, timestamp_s, matrix, &translation);
    message(2, "TRANSFORM", device, timestamp_s, &v1[HEADER_SIZE..])
}

/// PLUS's `Buttons` tool: buttons 1-3 in the first column (vtkPlusOpenHapticsDevice).
fn buttons(pressed: [bool; 3]) -> Matrix3<f64> {
    let mut m = Matrix3::zeros();
    for (row, on) in pressed.iter().enumerate() {
        m[(row, 0)] = if *on { 1.0 } else { 0.0 };
    }
    m
}

/// The fake PlusServer's connection: what it streams.
struct FakePlus {
    stream: TcpStream,
    t: f64,
}

impl FakePlus {
    fn accept(listener: &TcpListener) -> Self {
        let (stream, _) = listener.accept().expect("fissure's link connects");
        stream.set_nodelay(true).expect("nodelay");
        Self { stream, t: 1_700_000_000.0 }
    }

    /// One acquisition: the stylus at `mm` (device frame), its buttons, and a keep-alive.
    fn frame(&mut self, mm: [f64; 3], pressed: [bool; 3]) {
        self.t += 0.05;
        let mut bytes = plus_transform("StylusToBase", self.t, &Matrix3::identity(), Vec3::from(mm));
        bytes.extend(plus_transform("ButtonsToBase", self.t, &buttons(pressed), Vec3::zeros()));
        bytes.extend(message(2, "STATUS", "", self.t, &[0u8; 30]));
        // A tool fissure does not read: counted as ignored, not published.
        bytes.extend(plus_transform("StylusVelocityToBase", self.t, &Matrix3::identity(), Vec3::new(5.0, 0.0, 0.0)));
        self.stream.write_all(&bytes).expect("stream to fissure");
    }
}

/// Reads one message from fissure's server: (type, device, content).
fn read_message(stream: &mut TcpStream) -> (String, String, Vec<u8>) {
    let mut header = [0u8; HEADER_SIZE];
    stream.read_exact(&mut header).expect("a header");
    let h = decode_header(&header).expect("a valid header");
    let mut body = vec![0u8; h.body_size as usize];
    stream.read_exact(&mut body).expect("a body");
    (h.message_type.clone(), h.device.clone(), body)
}

fn scene(plus_port: u16) -> Scenario {
    let path = Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/config/sylvian.ron"));
    let text = std::fs::read_to_string(path).expect("read");
    // The Touch in front of the screen: its base frame's x and y are the scene's -x and -y.
    let input = format!(
        "spatulas[0].input=OpenIgtLink(device: \"StylusToBase\", connect: \"127.0.0.1:{plus_port}\", \
         mapping: (scale: 0.5, rotation: AxisAngle(axis: (0.0, 0.0, 1.0), angle_deg: 180.0), clutch: (device: \"ButtonsToBase\", button: 1)), \
         force: (name: \"ForceToBase\", scale: 0.5, max_force_n: 1.0, rate_hz: 50.0))"
    );
    Scenario::from_str(&text, path, &[input, "openigtlink.listen=\"127.0.0.1:0\"".to_string()]).expect("the stylus scene validates")
}

#[test]
fn a_stylus_through_plus_drives_a_blade_and_feels_its_force_across_a_server_restart() {
    let plus = TcpListener::bind("127.0.0.1:0").expect("the fake PlusServer listens");
    let plus_addr: SocketAddr = plus.local_addr().expect("its address");
    let scenario = scene(plus_addr.port());
    let origin = scenario.spatulas[0].initial_pose;
    let mut config = igtl_config(&scenario).expect("an OpenIGTLink binding");
    config.backoff = Backoff { first_ms: 20, max_ms: 200 };
    let mut server = IgtlServer::start(&config).expect("fissure's endpoint");
    let blade = |server: &IgtlServer| server.latest("StylusToBase").map(|t| t.pose);

    // PLUS's OpenIGTLinkTracker (the force channel) connects to fissure's server.
    let fissure_addr = server.listening_on().expect("force back: fissure listens");
    let mut force_channel = TcpStream::connect(fissure_addr).expect("PLUS's force channel connects");
    force_channel.set_read_timeout(Some(Duration::from_secs(10))).expect("timeout");
    wait_until(|| server.stats().clients_accepted == 1, "the force channel's connection");

    // The stylus's first pose maps to the blade's scenario pose, wherever the stylus is.
    let mut link = FakePlus::accept(&plus);
    wait_until(|| server.link_status()[0].connected(), "the link's status");
    link.frame([10.0, 20.0, 30.0], [false; 3]);
    wait_until(|| blade(&server).is_some(), "the first stylus pose");
    let first = blade(&server).unwrap();
    assert!((first.position - origin.position).norm() < 1e-9 && first.rotation.angle_to(&origin.rotation) < 1e-6, "{first:?} vs {origin:?}");

    // 20 mm along the device's x at scale 0.5 is 10 mm along the scene's -x.
    let moved = |server: &IgtlServer, expected: Vec3| {
        wait_until(|| blade(server).is_some_and(|p| (p.position - expected).norm() < 1e-6), &format!("the blade at {expected:?}"));
    };
    link.frame([30.0, 20.0, 30.0], [false; 3]);
    let after_move = origin.position + Vec3::new(-0.010, 0.0, 0.0);
    moved(&server, after_move);

    // The clutch (button 1): the stylus goes back 30 mm, the blade stays; released, it goes on from there.
    link.frame([30.0, 20.0, 30.0], [true, false, false]);
    wait_until(|| server.clutched("StylusToBase"), "the clutch");
    link.frame([0.0, 20.0, 30.0], [true, false, false]);
    link.frame([0.0, 20.0, 30.0], [false; 3]);
    wait_until(|| !server.clutched("StylusToBase"), "the clutch's release");
    // PLUS sends the pose before the buttons: the first pose after the release anchors.
    link.frame([0.0, 20.0, 30.0], [false; 3]);
    link.frame([0.0, 20.0, 50.0], [false; 3]);
    let recentred = after_move + Vec3::new(0.0, 0.0, 0.010);
    moved(&server, recentred);
    let stats = server.stats();
    assert!(stats.buttons_received >= 5 && stats.messages_ignored >= 5, "buttons read, keep-alives and the velocity tool skipped: {stats:?}");
    assert_eq!((stats.messages_rejected, stats.poses_refused()), (0, 0), "{stats:?}");

    // The force at the 1 kHz haptic loop's ticks for 0.2 s: 4 N along the scene's
    // x is 2 N along the device's -x at scale 0.5, clamped to the device's 1 N,
    // sent at 50 Hz (every 20 ms) as PLUS's force TRANSFORM, besides the SENSOR.
    let t0 = 2_000_000.0;
    for tick in 0..=200 {
        server.send_force("frontal", t0 + tick as f64 * 1e-3, [4.0, 0.0, 0.0]);
    }
    let mut transforms = Vec::new();
    let mut sensors = 0;
    while transforms.len() < 11 {
        let (kind, device, body) = read_message(&mut force_channel);
        match kind.as_str() {
            "SENSOR" => {
                assert_eq!(device, "Force_frontal");
                assert_eq!(decode_sensor_body(&body).expect("sensor").1, vec![4.0, 0.0, 0.0], "the SENSOR keeps the scene's force");
                sensors += 1;
            }
            "TRANSFORM" => transforms.push((device, body)),
            other => panic!("unexpected {other}"),
        }
    }
    assert!(sensors >= 200, "{sensors} SENSOR messages before the 11th TRANSFORM");
    for (device, body) in &transforms {
        assert_eq!(device, "ForceToBase");
        let header = decode_header(&message(1, "TRANSFORM", device, 0.0, body)).expect("header");
        let RawMessage::Transform(t) = decode_body_raw(&header, body).expect("a TRANSFORM") else { panic!("a TRANSFORM") };
        assert!((t.translation - Vec3::new(-1.0, 0.0, 0.0)).norm() < 1e-6, "the force in the device's frame, clamped: {:?}", t.translation);
        assert_eq!(t.matrix, Matrix3::identity());
    }
    let stats = server.stats();
    assert_eq!((stats.force_transforms_sent, stats.forces_clamped), (11, 11), "one TRANSFORM per 20 ms over 0.2 s, each clamped: {stats:?}");

    // Clutched, the hand moves freely: the force sent is zero.
    link.frame([0.0, 20.0, 50.0], [true, false, false]);
    wait_until(|| server.clutched("StylusToBase"), "the clutch again");
    server.send_force("frontal", t0 + 1.0, [4.0, 0.0, 0.0]);
    let zero = loop {
        let (kind, _, body) = read_message(&mut force_channel);
        if kind == "TRANSFORM" {
            break body;
        }
    };
    let header = decode_header(&message(1, "TRANSFORM", "ForceToBase", 0.0, &zero)).expect("header");
    let RawMessage::Transform(t) = decode_body_raw(&header, &zero).expect("raw") else { panic!("a TRANSFORM") };
    assert_eq!(t.translation, Vec3::zeros(), "no force while clutched");
    link.frame([0.0, 20.0, 50.0], [false; 3]);
    wait_until(|| !server.clutched("StylusToBase"), "the release");

    // The PlusServer restarts (its connection and its socket go, a new one binds the same port).
    drop(link);
    drop(plus);
    wait_until(|| !server.link_status()[0].connected(), "the link to notice");
    let held = blade(&server).expect("the blade's pose");
    assert!((held.position - recentred).norm() < 1e-9, "the blade holds while the server is gone");
    let plus = TcpListener::bind(plus_addr).expect("the PlusServer again, same port");
    let mut link = FakePlus::accept(&plus);
    wait_until(|| server.link_status()[0].connected(), "the reconnection");
    assert_eq!(server.link_status()[0].connections, 2);
    // The stylus was moved while the server was down: its first pose re-anchors, no jump.
    link.frame([80.0, -40.0, 10.0], [false; 3]);
    link.frame([80.0, -40.0, 30.0], [false; 3]);
    moved(&server, recentred + Vec3::new(0.0, 0.0, 0.010));
    assert_eq!(server.stats().links_connected, 2);
    assert_eq!(server.stats().poses_refused(), 0, "no jump for the speed check to refuse");
}

#[test]
fn an_unreachable_plus_server_is_retried_and_said_so_without_blocking() {
    // A port with nothing behind it: bind, note, close.
    let port = TcpListener::bind("127.0.0.1:0").expect("bind").local_addr().expect("addr").port();
    let mut config = igtl_config(&scene(port)).expect("bound");
    config.backoff = Backoff { first_ms: 10, max_ms: 40 };
    let started = Instant::now();
    let server = IgtlServer::start(&config).expect("starts without its server");
    assert!(started.elapsed() < Duration::from_secs(1), "starting never waits on the link");
    wait_until(|| server.link_status()[0].to_string().contains("cannot connect"), "the status line");
    let line = server.link_status()[0].to_string();
    assert!(line.starts_with(&format!("OpenIGTLink 127.0.0.1:{port}: cannot connect")) && line.contains("the blade holds"), "{line}");
    let asked = Instant::now();
    assert!(server.latest("StylusToBase").is_none());
    assert!(asked.elapsed() < Duration::from_millis(100), "a poll answers at once");
    // It keeps trying: a server that appears later is found.
    let plus = TcpListener::bind(("127.0.0.1", port)).expect("rebind");
    let _link = FakePlus::accept(&plus);
    wait_until(|| server.link_status()[0].connected(), "the late server");
}

/// One element of an XML file: its name, its attributes, and the chain of
/// `Id`s of the `Device` it sits in (empty outside a device).
#[derive(Debug)]
struct Element {
    name: String,
    attributes: Vec<(String, String)>,
    device: Option<String>,
}

impl Element {
    fn get(&self, key: &str) -> Option<&str> {
        self.attributes.iter().find(|(k, _)| k == key).map(|(_, v)| v.as_str())
    }
}

fn elements(xml: &str) -> Vec<Element> {
    use quick_xml::events::Event;
    let mut reader = quick_xml::Reader::from_str(xml);
    let mut out = Vec::new();
    // The device each open element sits in.
    let mut open: Vec<Option<String>> = Vec::new();
    loop {
        let event = reader.read_event().expect("well-formed XML");
        match event {
            Event::Start(ref e) | Event::Empty(ref e) => {
                let name = String::from_utf8_lossy(e.name().as_ref().as_bytes()).into_owned();
                let attributes: Vec<(String, String)> = e
                    .attributes()
                    .flatten()
                    .map(|a| (String::from_utf8_lossy(a.key.as_ref().as_bytes()).into_owned(), String::from_utf8_lossy(a.value.as_bytes()).into_owned()))
                    .collect();
                let element = Element { name, attributes, device: open.last().cloned().flatten() };
                let inner = if element.name == "Device" { element.get("Id").map(str::to_string) } else { element.device.clone() };
                out.push(element);
                if matches!(event, Event::Start(_)) {
                    open.push(inner);
                }
            }
            Event::End(_) => {
                open.pop();
            }
            Event::Eof => break,
            _ => {}
        }
    }
    out
}

/// The shipped PLUS configuration and the shipped scene agree: the transform
/// names fissure reads and sends, the two ports, and the force's rate.
#[test]
fn the_shipped_plus_configuration_matches_the_shipped_touch_scene() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let xml = std::fs::read_to_string(root.join("assets/devices/PlusDeviceSet_fissure_Touch.xml")).expect("shipped");
    let all = elements(&xml);
    let scenario = Scenario::load(&root.join("config/sylvian_touch.ron"), &[]).expect("the Touch scene validates");
    let fissure::scenario::InputBinding::OpenIgtLink { device, link, .. } = &scenario.spatulas[0].input else { panic!("the frontal blade is on the stylus") };
    let (clutch, _) = link.mapping.as_ref().and_then(|m| m.clutch.clone()).expect("a clutch");
    let force = link.force.as_ref().expect("force back");
    assert_eq!(scenario.spatulas[1].input, fissure::scenario::InputBinding::SpaceMouse);

    let device_of_type = |ty: &str| all.iter().find(|e| e.name == "Device" && e.get("Type") == Some(ty)).unwrap_or_else(|| panic!("a {ty} device"));
    let haptics = device_of_type("OpenHaptics");
    let frame = haptics.get("ToolReferenceFrame").expect("the OpenHaptics frame");
    let haptics_id = haptics.get("Id").expect("id");
    let tools: Vec<(&str, &str)> = all
        .iter()
        .filter(|e| e.name == "DataSource" && e.device.as_deref() == Some(haptics_id) && e.get("Type") == Some("Tool"))
        .map(|e| (e.get("Id").unwrap_or(""), e.get("PortName").unwrap_or("")))
        .collect();
    assert!(tools.contains(&("Stylus", "Stylus")) && tools.contains(&("Buttons", "Buttons")), "{tools:?}");
    assert_eq!(device.as_str(), format!("StylusTo{frame}"), "the pose PLUS sends");
    assert_eq!(clutch, format!("ButtonsTo{frame}"), "the buttons PLUS sends");

    let server = all.iter().find(|e| e.name == "PlusOpenIGTLinkServer").expect("the server");
    let connect = link.connect.as_deref().expect("fissure connects to PLUS");
    assert_eq!(connect.rsplit_once(':').map(|(_, p)| p), server.get("ListeningPort"), "fissure connects where PlusServer listens");
    let names: Vec<&str> = all.iter().filter(|e| e.name == "Transform").filter_map(|e| e.get("Name")).collect();
    assert!(names.contains(&device.as_str()) && names.contains(&clutch.as_str()), "PlusServer sends what fissure reads: {names:?}");

    let tracker = device_of_type("OpenIGTLinkTracker");
    assert_eq!(tracker.get("ServerPort").map(str::to_string), Some(scenario.devices.igtl_listen.port().to_string()), "PLUS's force channel connects to fissure's server");
    assert_eq!(tracker.get("MessageType"), Some("TRANSFORM"));
    let tracker_id = tracker.get("Id").expect("id");
    let force_tool = all
        .iter()
        .find(|e| e.name == "DataSource" && e.device.as_deref() == Some(tracker_id) && e.get("PortName") == Some("Force"))
        .expect("a tool with port name Force");
    assert_eq!(force.name, format!("{}To{}", force_tool.get("Id").expect("id"), tracker.get("ToolReferenceFrame").expect("frame")), "the TRANSFORM the tracker turns into its Force tool");
    let channel = all.iter().find(|e| e.name == "OutputChannel" && e.device.as_deref() == Some(tracker_id)).and_then(|e| e.get("Id")).expect("its channel");
    assert!(all.iter().any(|e| e.name == "InputChannel" && e.device.as_deref() == Some(haptics_id) && e.get("Id") == Some(channel)), "the OpenHaptics device's input channel is the force's");
    for d in [tracker, haptics] {
        assert_eq!(d.get("AcquisitionRate").and_then(|r| r.parse::<f64>().ok()), Some(force.rate_hz), "{:?} reads at the force's rate", d.get("Id"));
    }
}
