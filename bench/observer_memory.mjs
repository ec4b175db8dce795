// Memory per observer, client side (bench/observer_memory starts the server and this script):
// opens observers of "vehicle:<id>" step by step over raw Phoenix Channels v2 WebSockets (the
// `ws` package, worker threads), each joined and reading every frame; after each step waits
// OBSMEM_SETTLE_S (longer than a connection's idle check, every 15 s), checks that every
// observer receives telemetry at the vehicle's rate, and samples the server: RSS
// (/proc/<pid>/status) and, through a hidden Erlang node on the server's VM, erlang:memory()
// by type (taken first, before the probe allocates anything), process and port counts, yaws'
// WebSocket connection processes (children of yaws_ws_sup, one per connection: the process
// that runs NeptunusWeb.Socket) — memory, heap, stack, mailbox, the refc binaries they
// reference — their sockets (port memory, sndbuf/recbuf/buffer), and the largest other
// processes. Prints a table, then the deltas per observer against the first step. Prints
// figures, asserts nothing.
//
// Environment: OBSMEM_URL, OBSMEM_VEHICLE (neptunus-1), OBSMEM_STEPS ("0 250 500 1000 2000"),
// OBSMEM_SETTLE_S (20), OBSMEM_HZ (20, the expected telemetry rate), OBSMEM_SERVER_PID,
// OBSMEM_NODE, OBSMEM_COOKIE, OBSMEM_WINDOW (100 connects in flight).

import { createRequire } from 'node:module';
import { Worker, isMainThread, parentPort, workerData } from 'node:worker_threads';
import { readFileSync } from 'node:fs';
import { execFile } from 'node:child_process';
import { fileURLToPath } from 'node:url';
import { performance } from 'node:perf_hooks';
import os from 'node:os';

const require = createRequire(new URL('../assets/package.json', import.meta.url));
const WebSocket = require('ws');
const nowMs = () => performance.timeOrigin + performance.now();
const sleep = (ms) => new Promise((r) => setTimeout(r, ms));
const num = (v, d) => { const n = Number(v ?? ''); return Number.isFinite(n) && n > 0 ? n : d; };

const URL_BASE = process.env.OBSMEM_URL ?? 'ws://127.0.0.1:4214';
const VEHICLE = process.env.OBSMEM_VEHICLE ?? 'neptunus-1';
const TOPIC = `vehicle:${VEHICLE}`;
const wsUrl = (name) => `${URL_BASE}/socket/websocket?vsn=2.0.0&name=${name}`;

// The server-side figures, evaluated on the server's node: one line of flat JSON (integers).
const PROBE = `
Node = list_to_atom(os:getenv("OBSMEM_NODE")),
F = fun() ->
  Mem = erlang:memory(),
  Ws = [P || {_, P, _, _} <- supervisor:which_children(yaws_ws_sup), is_pid(P)],
  Keys = [memory, total_heap_size, heap_size, stack_size, message_queue_len, binary],
  {Sum, Max, Bins} = lists:foldl(fun(P, {S, M, B}) ->
      case erlang:process_info(P, Keys) of
        undefined -> {S, M, B};
        I ->
          Bin = proplists:get_value(binary, I),
          V = [proplists:get_value(K, I) || K <- [memory, total_heap_size, heap_size, stack_size, message_queue_len]]
              ++ [length(Bin), lists:sum([Sz || {_, Sz, _} <- Bin])],
          {lists:zipwith(fun(A, X) -> A + X end, S, V), max(M, hd(V)),
           lists:foldl(fun({Id, Sz, _}, Acc) -> Acc#{Id => Sz} end, B, Bin)}
      end end, {[0, 0, 0, 0, 0, 0, 0], 0, #{}}, Ws),
  WsSet = maps:from_list([{P, true} || P <- Ws]),
  Socks = [Po || Po <- erlang:ports(), erlang:port_info(Po, name) =:= {name, "tcp_inet"},
                 maps:is_key(element(2, erlang:port_info(Po, connected)), WsSet)],
  PortMem = lists:sum([element(2, erlang:port_info(Po, memory)) || Po <- Socks]),
  Opts = case Socks of
           [S1 | _] -> case inet:getopts(S1, [sndbuf, recbuf, buffer]) of {ok, O} -> O; _ -> [] end;
           [] -> []
         end,
  Name = fun(P) ->
    case erlang:process_info(P, [registered_name, dictionary, initial_call]) of
      undefined -> "gone";
      I -> case proplists:get_value(registered_name, I) of
             [] -> case proplists:get_value('$initial_call', proplists:get_value(dictionary, I)) of
                     {M, Fn, A} -> lists:flatten(io_lib:format("~s:~s/~b", [M, Fn, A]));
                     _ -> {M, Fn, A} = proplists:get_value(initial_call, I), lists:flatten(io_lib:format("~s:~s/~b", [M, Fn, A]))
                   end;
             N -> atom_to_list(N)
           end
    end
  end,
  Others = lists:sublist(lists:reverse(lists:sort(
    [{M, P} || P <- erlang:processes(), not maps:is_key(P, WsSet), {memory, M} <- [erlang:process_info(P, memory)]])), 6),
  Top = [{list_to_atom("top " ++ [C || C <- Name(P), C =/= $"]), M} || {M, P} <- Others],
  Top ++
  [{procs, erlang:system_info(process_count)}, {ports, length(erlang:ports())}, {conns, length(Ws)},
   {conn_sockets, length(Socks)}, {conn_port_memory, PortMem}, {conn_max_memory, Max},
   {conn_unique_binary_bytes, lists:sum(maps:values(Bins))}]
  ++ lists:zip([conn_memory, conn_total_heap_words, conn_heap_words, conn_stack_words, conn_queue,
                conn_binaries, conn_binary_bytes], Sum)
  ++ [{list_to_atom("mem_" ++ atom_to_list(K)), V} || {K, V} <- Mem]
  ++ [{list_to_atom("sock_" ++ atom_to_list(K)), V} || {K, V} <- Opts]
  ++ [{wordsize, erlang:system_info(wordsize)}]
end,
case rpc:call(Node, erlang, apply, [F, []], 60000) of
  L when is_list(L) ->
    io:format("~n{~s}~n", [lists:join(",", [io_lib:format("\\"~s\\":~b", [K, V]) || {K, V} <- L])]);
  Other -> io:format("~n{\\"error\\":\\"~s\\"}~n", [[C || C <- lists:flatten(io_lib:format("~p", [Other])), C =/= $", C =/= $\\\\]])
end,
halt().`;

async function main() {
  const STEPS = (process.env.OBSMEM_STEPS ?? '0 250 500 1000 2000').trim().split(/\s+/).map(Number).sort((a, b) => a - b);
  const SETTLE = num(process.env.OBSMEM_SETTLE_S, 20) * 1000;
  const HZ = num(process.env.OBSMEM_HZ, 20);
  const SERVER_PID = Number(process.env.OBSMEM_SERVER_PID ?? 0);
  const WINDOW = num(process.env.OBSMEM_WINDOW, 100);
  const rssKb = () => {
    try { return Number(/VmRSS:\s+(\d+)/.exec(readFileSync(`/proc/${SERVER_PID}/status`, 'utf8'))[1]); } catch { return NaN; }
  };
  const probe = () => new Promise((resolve) => {
    if (!process.env.OBSMEM_NODE) return resolve({ error: 'OBSMEM_NODE not set' });
    execFile('erl', ['-hidden', '-noshell', '-sname', `obsmemprobe${process.pid}`, '-setcookie', process.env.OBSMEM_COOKIE,
      '-eval', PROBE], { timeout: 90_000 }, (err, stdout) => {
      if (err) return resolve({ error: String(err.message).split('\n')[0] });
      try { resolve(JSON.parse(stdout.trim().split('\n').pop())); } catch { resolve({ error: stdout.slice(0, 200) }); }
    });
  });

  const WORKERS = 2;
  const workers = [];
  for (let w = 0; w < WORKERS; w++) {
    const worker = new Worker(fileURLToPath(import.meta.url), { workerData: { w, window: Math.max(1, Math.floor(WINDOW / WORKERS)) } });
    worker.on('error', (e) => { console.error('observer worker crashed:', e); process.exit(2); });
    workers.push(worker);
  }
  let seq = 0;
  const ask = (worker, cmd, extra = {}) => new Promise((resolve) => {
    const id = ++seq;
    const on = (m) => { if (m.id === id) { worker.off('message', on); resolve(m); } };
    worker.on('message', on); worker.postMessage({ id, cmd, ...extra });
  });

  console.log(`# observer_memory: steps ${STEPS.join(', ')} observers of ${TOPIC} (${URL_BASE}), ${SETTLE / 1000} s settle per step; ` +
    `${os.cpus().length} cores; load average ${os.loadavg().map((x) => x.toFixed(2)).join(' ')}`);
  const KiB = (b) => (b / 1024).toFixed(1);
  const MiB = (b) => (b / 1048576).toFixed(1);
  const cols = ['observers', 'joined', 'telem/s/obs', 'RSS MiB', 'total', 'processes', 'binary', 'ets', 'code+atom', 'procs', 'ports',
    'conn mem KiB', 'heap+stack KiB', 'refc bins (KiB)', 'queue', 'sock port B'];
  console.log('# erlang:memory() in MiB; conn = per connection process (yaws_websockets, one per observer), averages');
  console.log(cols.join(' | '));
  const rows = [];
  let open = 0;
  for (const step of STEPS) {
    const add = step - open;
    if (add > 0) {
      const ids = Array.from({ length: add }, (_, i) => open + i);
      await Promise.all(workers.map((w, k) => ask(w, 'open', { ids: ids.filter((_, i) => i % WORKERS === k) })));
      open = step;
    }
    await Promise.all(workers.map((w) => ask(w, 'count')));  // reset the frame counters
    const t0 = performance.now();
    await sleep(SETTLE);
    const counts = await Promise.all(workers.map((w) => ask(w, 'count')));
    const secs = (performance.now() - t0) / 1000;
    const joined = counts.reduce((a, c) => a + c.joined, 0);
    const frames = counts.reduce((a, c) => a + c.frames, 0);
    const starved = counts.reduce((a, c) => a + c.starved, 0);
    const closed = counts.reduce((a, c) => a + c.closedByServer, 0);
    const rss = rssKb() * 1024;
    const s = await probe();
    if (s.error) { console.log(`probe failed: ${s.error}`); process.exit(1); }
    const w = s.wordsize;
    const c = Math.max(1, s.conns);
    const row = { step, joined, rate: joined ? frames / secs / joined : NaN, starved, closed, rss, s };
    rows.push(row);
    console.log([step, joined, Number.isFinite(row.rate) ? row.rate.toFixed(1) : 'n/a', MiB(rss), MiB(s.mem_total), MiB(s.mem_processes),
      MiB(s.mem_binary), MiB(s.mem_ets), MiB(s.mem_code + s.mem_atom), s.procs, s.ports,
      s.conns ? `${KiB(s.conn_memory / c)} (max ${KiB(s.conn_max_memory)})` : '-',
      s.conns ? KiB(((s.conn_total_heap_words + s.conn_stack_words) * w) / c) : '-',
      s.conns ? `${(s.conn_binaries / c).toFixed(1)} (${KiB(s.conn_binary_bytes / c)}; ${KiB(s.conn_unique_binary_bytes)} distinct in all)` : '-',
      s.conns ? (s.conn_queue / c).toFixed(2) : '-',
      s.conn_sockets ? `${Math.round(s.conn_port_memory / s.conn_sockets)}` : '-'].join(' | '));
    console.log(`#   largest other processes: ${Object.entries(s).filter(([k]) => k.startsWith('top ')).map(([k, v]) => `${k.slice(4)} ${KiB(v)} KiB`).join(', ')}`);
    if (starved || closed) console.log(`#   ${starved} observers received fewer than ${HZ / 2} frames/s; ${closed} closed by the server`);
  }
  const base = rows[0];
  const any = rows.find((r) => r.s.conns > 0);
  if (any) console.log(`# sockets of the connections: sndbuf ${any.s.sock_sndbuf} B, recbuf ${any.s.sock_recbuf} B, buffer (driver) ${any.s.sock_buffer} B`);
  console.log(`# per observer, against ${base.step} observers (bytes): RSS | erlang:memory total | processes | binary | ets | system - binary - ets`);
  for (const r of rows) {
    if (r === base) continue;
    const n = r.step - base.step;
    const d = (k) => Math.round((r.s[k] - base.s[k]) / n);
    const sys = (x) => x.s.mem_system - x.s.mem_binary - x.s.mem_ets;
    console.log(`${String(r.step).padStart(6)}: ${Math.round((r.rss - base.rss) / n)} | ${d('mem_total')} | ${d('mem_processes')} | ` +
      `${d('mem_binary')} | ${d('mem_ets')} | ${Math.round((sys(r) - sys(base)) / n)}`);
  }
  await Promise.all(workers.map((w) => ask(w, 'close')));
  await Promise.all(workers.map((w) => w.terminate()));
  process.exit(0);
}

// A worker thread of observers: opens and joins the sockets it is given, counts the telemetry
// frames each receives, heartbeats every 30 s as the pages do.
function observers({ window }) {
  const sockets = [];
  let frames = 0, closedByServer = 0;
  const prefix = `[null,null,${JSON.stringify(TOPIC)},"telemetry",`;
  const openOne = (k) => new Promise((resolve) => {
    const ws = new WebSocket(wsUrl(`obs${k}`), { perMessageDeflate: false });
    ws.frames = 0; ws.joined = false;
    ws.on('message', (data) => {
      const text = data.toString();
      if (text.startsWith(prefix)) { frames++; ws.frames++; }
      else if (!ws.joined && text.startsWith('["j","j"')) { ws.joined = text.includes('"status":"ok"'); resolve(ws.joined); }
    });
    ws.once('open', () => ws.send(JSON.stringify(['j', 'j', TOPIC, 'phx_join', {}])));
    ws.once('error', () => resolve(false));
    ws.on('close', () => { if (!ws.closing) closedByServer++; });
    sockets.push(ws);
    setInterval(() => { if (ws.readyState === 1) ws.send(JSON.stringify([null, 'hb', 'phoenix', 'heartbeat', {}])); }, 30000).unref();
  });
  let since = performance.now();
  parentPort.on('message', async ({ id, cmd, ids }) => {
    if (cmd === 'open') {
      let next = 0;
      await Promise.all(Array.from({ length: Math.min(window, ids.length) }, async () => {
        while (next < ids.length) await openOne(ids[next++]);
      }));
      parentPort.postMessage({ id });
    } else if (cmd === 'count') {
      const secs = (performance.now() - since) / 1000;
      const joined = sockets.filter((ws) => ws.joined && ws.readyState === 1);
      const starved = joined.filter((ws) => ws.frames < secs * 10).length;
      parentPort.postMessage({ id, joined: joined.length, frames, starved, closedByServer });
      frames = 0; since = performance.now();
      for (const ws of sockets) ws.frames = 0;
    } else if (cmd === 'close') {
      for (const ws of sockets) { ws.closing = true; ws.close(1000); }
      await sleep(500);
      parentPort.postMessage({ id });
    }
  });
}

if (isMainThread) await main(); else observers(workerData);
