//! `launch --live`: a real Foxglove WebSocket client (tungstenite, the protocol's `foxglove.sdk.v1`
//! subprotocol) connects during a real-time fig1 run, subscribes to every channel, and the scene
//! and telemetry it receives equal the run's telemetry files for the same steps, for two clients
//! at once; `--live` changes no telemetry bit; a port in use is exit 2 before anything runs.

use std::collections::BTreeMap;
use std::net::{TcpListener, TcpStream};
use std::path::Path;
use std::process::Stdio;
use std::time::{Duration, Instant};

use cohort::{
    OutputWithin, QUICK_LIMIT, RUN_LIMIT, finish_within, heavy_scratch, orchestrator_command, repo_root,
    telemetry_bits, telemetry_table,
};
use tungstenite::client::IntoClientRequest;
use tungstenite::{Message, WebSocket};

/// A port nobody listens on now (the kernel's choice, released at once).
pub(crate) fn free_port() -> u16 {
    TcpListener::bind("127.0.0.1:0").unwrap().local_addr().unwrap().port()
}

/// What one client received: per topic, (log time ns, payload).
pub(crate) type Received = BTreeMap<String, Vec<(u64, Vec<u8>)>>;

/// Connect (retrying until the server listens, up to `limit`), subscribe to every channel as it
/// is advertised, and read until the server goes away.
pub(crate) fn client(port: u16, limit: Duration) -> Received {
    let started = Instant::now();
    let mut ws: WebSocket<TcpStream> = loop {
        let mut req = format!("ws://127.0.0.1:{port}").into_client_request().unwrap();
        req.headers_mut().insert("Sec-WebSocket-Protocol", "foxglove.sdk.v1".parse().unwrap());
        if let Ok(stream) = TcpStream::connect(("127.0.0.1", port)) {
            stream.set_read_timeout(Some(Duration::from_secs(30))).unwrap();
            if let Ok((ws, _)) = tungstenite::client::client(req, stream) {
                break ws;
            }
        }
        assert!(started.elapsed() < limit, "no live server on port {port} after {limit:?}");
        std::thread::sleep(Duration::from_millis(50));
    };
    let mut topics = BTreeMap::new();
    let mut got = Received::new();
    let mut retries = 0;
    while let Ok(msg) = ws.read() {
        match msg {
            Message::Text(text) => {
                let v: serde_json::Value = serde_json::from_str(&text).unwrap();
                // Shown when the test fails (the harness captures it otherwise).
                eprintln!("client on port {port}: {}", &text[..text.len().min(300)]);
                // The SDK (0.30) sends a channel's advertisement before it records the channel as
                // advertised to the client, so a subscription sent at once can come back as
                // unknown: subscribe again, as a client that reconnects panels would.
                let unknown = v["message"].as_str().and_then(|m| m.strip_prefix("Unknown channel ID: "));
                if v["op"] == "status"
                    && let Some(id) = unknown.and_then(|id| id.parse::<u64>().ok())
                {
                    retries += 1;
                    assert!(retries < 1000, "the server keeps refusing subscriptions");
                    std::thread::sleep(Duration::from_millis(10));
                    let sub = serde_json::json!({"op": "subscribe", "subscriptions": [{"id": id, "channelId": id}]});
                    ws.send(Message::text(sub.to_string())).unwrap();
                    continue;
                }
                if v["op"] != "advertise" {
                    continue;
                }
                let mut subs = Vec::new();
                for ch in v["channels"].as_array().unwrap() {
                    let id = ch["id"].as_u64().unwrap();
                    topics.insert(id, ch["topic"].as_str().unwrap().to_string());
                    subs.push(serde_json::json!({"id": id, "channelId": id}));
                }
                let sub = serde_json::json!({"op": "subscribe", "subscriptions": subs});
                ws.send(Message::text(sub.to_string())).unwrap();
            }
            Message::Binary(b) if b.first() == Some(&1) => {
                let sub = u32::from_le_bytes(b[1..5].try_into().unwrap()) as u64;
                let t = u64::from_le_bytes(b[5..13].try_into().unwrap());
                got.entry(topics[&sub].clone()).or_default().push((t, b[13..].to_vec()));
            }
            _ => {}
        }
    }
    got
}

/// A flat JSON object's numbers as written (Rust's parser reads the shortest form back exactly;
/// null is NaN).
pub(crate) fn json_numbers(payload: &[u8]) -> BTreeMap<String, f64> {
    let text = std::str::from_utf8(payload).unwrap();
    let inner = text.trim().trim_start_matches('{').trim_end_matches('}');
    inner
        .split(',')
        .map(|kv| {
            let (k, v) = kv.split_once(':').unwrap();
            (k.trim_matches('"').to_string(), if v == "null" { f64::NAN } else { v.parse().unwrap() })
        })
        .collect()
}

fn launch_live(out: &Path, port: u16, extra: &[&str]) -> std::process::Child {
    orchestrator_command()
        .args(["launch", "topologies/fig1.toml", "--no-plots", "--live"])
        .arg(format!("127.0.0.1:{port}"))
        .arg("--out")
        .arg(out)
        .args(extra)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap()
}

#[test]
fn two_clients_get_scene_and_telemetry_equal_to_the_runs_rows() {
    let (_g, dir) = heavy_scratch("live");
    let run = dir.join("run");
    let port = free_port();
    let child = launch_live(&run, port, &["--duration", "8", "--realtime"]);
    let clients: Vec<_> = (0..2).map(|_| std::thread::spawn(move || client(port, Duration::from_secs(120)))).collect();
    // A third client connects late, once the plant has journalled a second of steps.
    let deadline = Instant::now() + Duration::from_secs(120);
    while std::fs::metadata(run.join("telemetry/plant.rows")).map_or(0, |m| m.len()) < 100 * 8 * 20 {
        assert!(Instant::now() < deadline, "the plant journalled no telemetry");
        std::thread::sleep(Duration::from_millis(20));
    }
    // The view reads the journals every 50 ms: give it time to publish those rows first.
    std::thread::sleep(Duration::from_secs(2));
    let late = std::thread::spawn(move || client(port, Duration::from_secs(120)));
    let out = finish_within(child, RUN_LIMIT, "orchestrator launch --live");
    assert!(out.status.success(), "{}", cohort::describe_output(&out));
    let plant = telemetry_table(&run, "plant");
    let agent = telemetry_table(&run, "agent-2");
    let row_of = |t: &cohort_report::Table, k: u64| t.k.iter().position(|&x| x == k).unwrap();
    for c in clients {
        let got = c.join().unwrap();
        for topic in ["/scene", "/telemetry/plant", "/telemetry/agent-2", "/roster", "/progress"] {
            assert!(got.get(topic).is_some_and(|m| !m.is_empty()), "no {topic} message; got {:?}", got.keys());
        }
        for (topic, table) in [("/telemetry/plant", &plant), ("/telemetry/agent-2", &agent)] {
            for (_, payload) in &got[topic] {
                let row = json_numbers(payload);
                let r = row_of(table, row["k"] as u64);
                assert_eq!(row["t_s"].to_bits(), table.t[r].to_bits(), "{topic} step {}: t_s", row["k"]);
                for c in &table.columns {
                    assert_eq!(row[&c.name].to_bits(), c.values[r].to_bits(), "{topic} step {}: {}", row["k"], c.name);
                }
            }
        }
        // Each scene at step k holds agent 1's truth, the plant's b1_q_lvlh_*_m of step k, as the
        // protobuf doubles of its sphere's position.
        let x = plant.get("b1_q_lvlh_x_m").unwrap();
        for (t_ns, payload) in &got["/scene"] {
            let k = (*t_ns as f64 / 1e7).round() as u64;
            let bytes = x[row_of(&plant, k)].to_le_bytes();
            assert!(payload.windows(8).any(|w| w == bytes), "scene of step {k} lacks agent 1's truth x");
        }
        let roster = String::from_utf8_lossy(&got["/roster"][0].1).to_string();
        assert!(roster.contains("all on the roster"), "{roster}");
        // A later client's subscription resends the latest state to it alone: no duplicates here.
        for topic in ["/telemetry/plant", "/telemetry/agent-2", "/scene"] {
            let t: Vec<u64> = got[topic].iter().map(|m| m.0).collect();
            assert!(t.windows(2).all(|w| w[0] < w[1]), "{topic}: log times not increasing: {t:?}");
        }
    }
    // The late client got the roster's first line (sent before it came) and rows from mid-run on.
    let got = late.join().unwrap();
    let roster = String::from_utf8_lossy(&got["/roster"][0].1).to_string();
    assert!(roster.contains("all on the roster"), "late client's roster: {roster}");
    let first_k = got["/telemetry/plant"][0].0;
    assert!(first_k > 0, "the late client's first plant row is of step 0");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn live_changes_no_telemetry_bit_and_a_port_in_use_is_exit_2() {
    let (_g, dir) = heavy_scratch("live-bits");
    let (plain, live) = (dir.join("plain"), dir.join("live"));
    let o = cohort::launch_scenario(Path::new("topologies/fig1.toml"), &plain, &["--duration", "2"]);
    assert!(o.status.success(), "{}", cohort::describe_output(&o));
    let child = launch_live(&live, free_port(), &["--duration", "2"]);
    let o = finish_within(child, RUN_LIMIT, "orchestrator launch --live");
    assert!(o.status.success(), "{}", cohort::describe_output(&o));
    assert_eq!(telemetry_bits(&plain), telemetry_bits(&live), "--live changed the telemetry");

    let taken = TcpListener::bind("127.0.0.1:0").unwrap();
    let port = taken.local_addr().unwrap().port();
    let refused = dir.join("refused");
    let o = orchestrator_command()
        .current_dir(repo_root())
        .args(["launch", "topologies/fig1.toml", "--no-plots", "--live"])
        .arg(format!("127.0.0.1:{port}"))
        .arg("--out")
        .arg(&refused)
        .output_within(QUICK_LIMIT, "launch --live on a port in use");
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{}", cohort::describe_output(&o));
    assert!(err.contains(&format!("--live 127.0.0.1:{port}: cannot listen there")), "{err}");
    assert!(!refused.exists(), "a refused launch created its run directory");
    drop(taken);
    std::fs::remove_dir_all(&dir).unwrap();
}
