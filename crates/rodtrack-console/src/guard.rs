//! Request checks in front of every route: the console serves only its own page.
//!
//! - **Host**: a request whose `Host` is not an IP address (the bound one, or any literal
//!   address when bound to all interfaces), `localhost`, or a name allowed with
//!   `--allow-host` is refused (403): a DNS-rebinding page names its own domain.
//! - **Origin**: a state-changing request (`POST`, `PUT`, `DELETE`, `PATCH`) and the WebSocket
//!   upgrade are refused (403) when their `Origin` is not the console's own
//!   (`http://` + the request's `Host`).
//! - **Session token**: a state-changing request must carry the token of this console in the
//!   header [`TOKEN_HEADER`]; the page receives it in a `<meta name="rodtrack-token">` tag, and
//!   its script sends it. A page on another origin cannot read it.

use axum::body::Body;
use axum::extract::State;
use axum::http::{header, HeaderMap, Method, Request, StatusCode};
use axum::middleware::Next;
use axum::response::{IntoResponse, Response};
use axum::Json;
use serde_json::json;
use std::net::{IpAddr, SocketAddr};
use std::sync::Arc;

/// The header that carries the session token on state-changing requests.
pub const TOKEN_HEADER: &str = "x-rodtrack-token";

/// What the guard checks against.
#[derive(Debug, Clone)]
pub(crate) struct GuardConfig {
    /// The bound address.
    pub addr: SocketAddr,
    /// Host names allowed besides IP addresses and `localhost` (lower case, without port).
    pub allowed_hosts: Vec<String>,
    /// This console's session token.
    pub token: String,
}

/// A fresh random session token (128 bits, hex), from the standard library's per-process
/// random hasher keys, the time and the process id.
pub(crate) fn new_token() -> String {
    use std::collections::hash_map::RandomState;
    use std::hash::{BuildHasher, Hasher};
    let mut out = String::new();
    for i in 0..2u64 {
        let mut h = RandomState::new().build_hasher();
        h.write_u64(i);
        h.write_u128(
            std::time::SystemTime::now()
                .duration_since(std::time::UNIX_EPOCH)
                .map_or(0, |d| d.as_nanos()),
        );
        h.write_u32(std::process::id());
        out.push_str(&format!("{:016x}", h.finish()));
    }
    out
}

/// `host[:port]` split; IPv6 literals in brackets.
fn host_and_port(s: &str) -> (&str, Option<&str>) {
    if let Some(rest) = s.strip_prefix('[') {
        if let Some(end) = rest.find(']') {
            let port = rest[end + 1..].strip_prefix(':');
            return (&rest[..end], port);
        }
        return (s, None);
    }
    match s.rsplit_once(':') {
        Some((h, p)) if !h.contains(':') => (h, Some(p)),
        _ => (s, None),
    }
}

impl GuardConfig {
    /// True when `host` (a `Host` header value) names this console.
    pub fn host_allowed(&self, host: &str) -> bool {
        let (name, port) = host_and_port(host.trim());
        if port.is_some_and(|p| p != self.addr.port().to_string()) {
            return false;
        }
        let name = name.to_ascii_lowercase();
        if name == "localhost" || self.allowed_hosts.contains(&name) {
            return true;
        }
        match name.parse::<IpAddr>() {
            Ok(ip) => {
                ip == self.addr.ip()
                    || self.addr.ip().is_unspecified()
                    || (self.addr.ip().is_loopback() && ip.is_loopback())
            }
            Err(_) => false,
        }
    }

    /// True when `origin` is this console's own origin for a request to `host`.
    pub fn origin_allowed(&self, origin: &str, host: &str) -> bool {
        match origin.strip_prefix("http://") {
            Some(o) => o.eq_ignore_ascii_case(host) && self.host_allowed(o),
            None => false,
        }
    }
}

fn refuse(reason: String) -> Response {
    (StatusCode::FORBIDDEN, Json(json!({ "error": reason }))).into_response()
}

fn header_str(h: &HeaderMap, name: impl header::AsHeaderName) -> Option<&str> {
    h.get(name).and_then(|v| v.to_str().ok())
}

/// Checks a request (see the module documentation); `None` lets it through.
pub(crate) fn check(
    g: &GuardConfig,
    method: &Method,
    path: &str,
    h: &HeaderMap,
) -> Option<Response> {
    let Some(host) = header_str(h, header::HOST) else {
        return Some(refuse("no Host header".into()));
    };
    if !g.host_allowed(host) {
        return Some(refuse(format!(
            "Host `{host}` is not this console's address (start it with --allow-host {} to \
             serve that name)",
            host_and_port(host).0
        )));
    }
    let changes = matches!(
        *method,
        Method::POST | Method::PUT | Method::DELETE | Method::PATCH
    );
    if changes || path == "/ws" {
        if let Some(origin) = header_str(h, header::ORIGIN) {
            if !g.origin_allowed(origin, host) {
                return Some(refuse(format!(
                    "Origin `{origin}` is not this console's own: cross-origin request refused"
                )));
            }
        }
    }
    if changes && header_str(h, TOKEN_HEADER) != Some(g.token.as_str()) {
        return Some(refuse(format!(
            "missing or wrong session token (header {TOKEN_HEADER}, given to the console's page)"
        )));
    }
    None
}

/// The middleware: [`check`] before every route.
pub(crate) async fn guard(
    State(g): State<Arc<GuardConfig>>,
    req: Request<Body>,
    next: Next,
) -> Response {
    if let Some(r) = check(&g, req.method(), req.uri().path(), req.headers()) {
        return r;
    }
    next.run(req).await
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cfg(addr: &str) -> GuardConfig {
        GuardConfig {
            addr: addr
                .parse()
                .unwrap_or_else(|_| SocketAddr::from(([127, 0, 0, 1], 1))),
            allowed_hosts: vec!["table.lan".into()],
            token: "t0k".into(),
        }
    }

    #[test]
    fn hosts() {
        let g = cfg("127.0.0.1:8620");
        assert!(g.host_allowed("127.0.0.1:8620"));
        assert!(g.host_allowed("localhost:8620"));
        assert!(g.host_allowed("LOCALHOST"));
        assert!(g.host_allowed("table.lan:8620"));
        assert!(!g.host_allowed("evil.example"));
        assert!(!g.host_allowed("evil.example:8620"));
        assert!(!g.host_allowed("127.0.0.1:9999"));
        assert!(!g.host_allowed("10.0.0.5:8620"));
        let any = cfg("0.0.0.0:8620");
        assert!(any.host_allowed("10.0.0.5:8620"));
        assert!(!any.host_allowed("evil.example:8620"));
        let v6 = cfg("[::1]:8620");
        assert!(v6.host_allowed("[::1]:8620"));
    }

    #[test]
    fn origins() {
        let g = cfg("127.0.0.1:8620");
        assert!(g.origin_allowed("http://127.0.0.1:8620", "127.0.0.1:8620"));
        assert!(!g.origin_allowed("http://evil.example", "127.0.0.1:8620"));
        assert!(!g.origin_allowed("http://localhost:8620", "127.0.0.1:8620"));
        assert!(!g.origin_allowed("null", "127.0.0.1:8620"));
    }
}
