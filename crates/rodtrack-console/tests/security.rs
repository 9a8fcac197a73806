//! The console serves only its own page: cross-origin state changes, foreign `Host` headers
//! (DNS rebinding), cross-origin WebSockets and requests without the page's session token are
//! refused (issue "hostile input").
#![allow(missing_docs, clippy::unwrap_used)]

mod common;

use common::{get_json, http, http_with, page_token};
use rodtrack_console::calib::{default_inputs, new_rod};
use rodtrack_console::{
    CalibrationContext, CameraSetup, Console, ConsoleHandle, ConsoleOptions, OwnedFrame,
};
use rodtrack_core::{FrameView, PixelFormat};
use std::net::TcpStream;

const W: usize = 64;
const H: usize = 48;

/// A console with one camera and rods 0 and 1.
fn console(options: &ConsoleOptions) -> ConsoleHandle {
    let px = vec![128u8; W * H];
    let view = FrameView::packed(&px, W, H, PixelFormat::Mono8).unwrap();
    let owned = OwnedFrame::from_view(&view, 0, 0.0);
    let mut inputs = default_inputs(0, &owned);
    inputs.rods.push(new_rod(0, [-50.0, 50.0]));
    inputs.rods.push(new_rod(1, [-50.0, 50.0]));
    Console::start_with(
        "127.0.0.1:0".parse().unwrap(),
        Some(CalibrationContext {
            out_path: None,
            cameras: vec![CameraSetup {
                index: 0,
                inputs,
                reference: Some(owned),
            }],
        }),
        options,
    )
    .unwrap()
}

fn rods(c: &ConsoleHandle) -> usize {
    let state = get_json(c.addr(), "/api/calib");
    state["cameras"][0]["inputs"]["rods"]
        .as_array()
        .map_or(0, Vec::len)
}

#[test]
fn cross_origin_state_changes_are_refused() {
    let c = console(&ConsoleOptions::default());
    let addr = c.addr();
    assert_eq!(rods(&c), 2);
    let token = page_token(addr);
    assert_eq!(token, c.token());
    assert!(token.len() >= 32, "{token}");
    let evil = [("Origin", "http://evil.example")];
    for path in [
        "/api/calib/0/rods/0/delete",
        "/api/calibrate",
        "/api/save",
        "/api/calib/0/freeze",
    ] {
        // Without the token, and with it (as if it had leaked), from another origin.
        let (st, _) = http_with(addr, "POST", path, None, &evil);
        assert_eq!(st, 403, "{path}");
        let with = [evil[0], ("X-Rodtrack-Token", token.as_str())];
        let (st, body) = http_with(addr, "POST", path, None, &with);
        assert_eq!(st, 403, "{path}");
        assert!(String::from_utf8_lossy(&body).contains("Origin"), "{path}");
    }
    assert_eq!(rods(&c), 2, "a refused request changed the state");

    // No Origin (curl) and no token: refused too.
    let (st, _) = http_with(addr, "POST", "/api/calib/0/rods/0/delete", None, &[]);
    assert_eq!(st, 403);
    let wrong = [("X-Rodtrack-Token", "0123456789abcdef0123456789abcdef")];
    let (st, _) = http_with(addr, "POST", "/api/calib/0/rods/0/delete", None, &wrong);
    assert_eq!(st, 403);
    assert_eq!(rods(&c), 2);

    // The page's own origin with its token: served.
    let own = format!("http://{addr}");
    let ok = [
        ("Origin", own.as_str()),
        ("X-Rodtrack-Token", token.as_str()),
    ];
    let (st, body) = http_with(addr, "POST", "/api/calib/0/rods/0/delete", None, &ok);
    assert_eq!(st, 200, "{}", String::from_utf8_lossy(&body));
    assert_eq!(rods(&c), 1);
    // The test client's helper sends the token like the page does.
    let (st, _) = http(addr, "POST", "/api/calib/0/rods/1/delete", None);
    assert_eq!(st, 200);
    assert_eq!(rods(&c), 0);
}

#[test]
fn foreign_host_headers_are_refused_unless_allowed() {
    let c = console(&ConsoleOptions::default());
    let addr = c.addr();
    let port = addr.port();
    for host in [
        "evil.example".to_string(),
        format!("evil.example:{port}"),
        format!("127.0.0.1.evil.example:{port}"),
        format!("127.0.0.1:{}", port.wrapping_add(1)),
    ] {
        let (st, _) = http_with(addr, "GET", "/", None, &[("Host", host.as_str())]);
        assert_eq!(st, 403, "Host {host}");
        let (st, _) = http_with(addr, "GET", "/api/calib", None, &[("Host", host.as_str())]);
        assert_eq!(st, 403, "Host {host}");
    }
    for host in [format!("127.0.0.1:{port}"), format!("localhost:{port}")] {
        let (st, _) = http_with(addr, "GET", "/", None, &[("Host", host.as_str())]);
        assert_eq!(st, 200, "Host {host}");
    }

    let allowed = console(&ConsoleOptions {
        allowed_hosts: vec!["Table.LAN".into()],
    });
    let host = format!("table.lan:{}", allowed.addr().port());
    let (st, _) = http_with(allowed.addr(), "GET", "/", None, &[("Host", host.as_str())]);
    assert_eq!(st, 200);
    let (st, _) = http_with(
        allowed.addr(),
        "GET",
        "/",
        None,
        &[("Host", "evil.example")],
    );
    assert_eq!(st, 403);
}

fn ws_handshake(c: &ConsoleHandle, origin: Option<&str>) -> Result<(), String> {
    use tungstenite::client::IntoClientRequest;
    let mut req = format!("ws://{}/ws", c.addr())
        .into_client_request()
        .unwrap();
    if let Some(o) = origin {
        req.headers_mut().insert("Origin", o.parse().unwrap());
    }
    let stream = TcpStream::connect(c.addr()).unwrap();
    tungstenite::client::client(req, stream)
        .map(|_| ())
        .map_err(|e| e.to_string())
}

#[test]
fn the_websocket_checks_its_origin() {
    let c = console(&ConsoleOptions::default());
    let e = ws_handshake(&c, Some("http://evil.example")).unwrap_err();
    assert!(e.contains("403"), "{e}");
    ws_handshake(&c, Some(&format!("http://{}", c.addr()))).unwrap();
    // Clients that send no Origin (not a browser) are served.
    ws_handshake(&c, None).unwrap();
}
