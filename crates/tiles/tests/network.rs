//! A tile server that cannot be reached is reported with the true cause (issue 23, item 8): "offline" only
//! when the host name does not resolve, "refused" when nothing listens, never "has none here" (that is the
//! server's own 404). Real sockets: a port of 127.0.0.1 that is bound but not listening, and a name under
//! `.invalid`, which RFC 6761 reserves so that it never resolves.
#![allow(clippy::unwrap_used)]

use vestnav_tiles::store::TileClient;
use vestnav_tiles::{NetworkCause, TileError};

fn cause(url: &str) -> NetworkCause {
    let client = TileClient::new("the map").unwrap();
    match client.download(url, "tile 0/0/0") {
        Err(TileError::Network { cause, .. }) => cause,
        other => panic!("{url}: expected a network error, got {other:?}"),
    }
}

#[test]
fn a_closed_port_is_refused_not_offline() {
    // Bound, never listening: refused for the whole test, and no other socket can take it meanwhile.
    let refusing = vestnav_device::testkit::RefusingPort::bind().unwrap();
    let port = refusing.port();
    let c = cause(&format!("http://127.0.0.1:{port}/0/0/0.png"));
    assert_eq!(c, NetworkCause::Refused { host: format!("127.0.0.1:{port}") });
    assert!(c.to_string().contains("refused the connection"), "{c}");
}

#[test]
fn an_unresolvable_name_is_offline() {
    let c = cause("http://tiles.vestnav-test.invalid/0/0/0.png");
    assert!(matches!(c, NetworkCause::Offline { .. }), "{c:?}");
    assert_eq!(
        c.to_string(),
        "offline: tiles.vestnav-test.invalid cannot be resolved (no network or no DNS)"
    );
}
