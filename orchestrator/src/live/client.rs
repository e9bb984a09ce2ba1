//! A minimal Foxglove WebSocket client for the bench's live rows (`orchestrator bench --only
//! live`): it subscribes to every channel the server advertises and then either reads every
//! message (a viewer) or never reads again (a stalled viewer, whose queue the server must drop
//! rather than slow anything).

use std::net::TcpStream;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::thread::JoinHandle;
use std::time::Duration;

use tungstenite::client::IntoClientRequest;
use tungstenite::{Message, WebSocket};

/// A client on its own thread, until [`Client::stop`].
pub struct Client {
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<()>>,
}

fn connect(port: u16) -> Result<WebSocket<TcpStream>, String> {
    let mut req = format!("ws://127.0.0.1:{port}").into_client_request().map_err(|e| e.to_string())?;
    req.headers_mut().insert("Sec-WebSocket-Protocol", tungstenite::http::HeaderValue::from_static("foxglove.sdk.v1"));
    let stream = TcpStream::connect(("127.0.0.1", port)).map_err(|e| e.to_string())?;
    stream.set_read_timeout(Some(Duration::from_millis(100))).map_err(|e| e.to_string())?;
    tungstenite::client::client(req, stream).map(|(ws, _)| ws).map_err(|e| e.to_string())
}

/// Subscribe to every channel of an `advertise` message.
fn subscribe(ws: &mut WebSocket<TcpStream>, text: &str) {
    let Ok(v) = serde_json::from_str::<serde_json::Value>(text) else { return };
    if v["op"] != "advertise" {
        return;
    }
    let subs: Vec<_> = v["channels"]
        .as_array()
        .into_iter()
        .flatten()
        .filter_map(|c| c["id"].as_u64())
        .map(|id| serde_json::json!({"id": id, "channelId": id}))
        .collect();
    let _ = ws.send(Message::text(serde_json::json!({"op": "subscribe", "subscriptions": subs}).to_string()));
}

impl Client {
    /// Connect to the server on `port`; `reads`: go on reading (else stop reading once the first
    /// channels are subscribed).
    pub fn start(port: u16, reads: bool) -> Result<Client, String> {
        let mut ws = connect(port)?;
        let stop = Arc::new(AtomicBool::new(false));
        let stopping = Arc::clone(&stop);
        let thread = std::thread::spawn(move || {
            let mut subscribed = false;
            while !stopping.load(Ordering::Relaxed) {
                if subscribed && !reads {
                    std::thread::sleep(Duration::from_millis(50));
                    continue;
                }
                match ws.read() {
                    Ok(Message::Text(t)) => {
                        subscribe(&mut ws, &t);
                        subscribed = true;
                    }
                    Ok(_) => {}
                    Err(tungstenite::Error::Io(e))
                        if matches!(e.kind(), std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut) => {}
                    Err(_) => return,
                }
            }
        });
        Ok(Client { stop, thread: Some(thread) })
    }

    pub fn stop(mut self) {
        self.stop.store(true, Ordering::Relaxed);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}
