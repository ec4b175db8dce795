// Shared by the benchmarks: a raw Phoenix Channels v2 socket over the `ws` package (no phoenix
// client in between, so the bench measures the server). push() resolves with the phx_reply
// payload; other events go to client.onEvent(event, payload).
//
//   const client = await channelsSocket(WebSocket, url, { onClosed(code) { … } });
export function channelsSocket(WebSocket, url, { onClosed } = {}) {
  return new Promise((resolve, reject) => {
    const ws = new WebSocket(url, { perMessageDeflate: false });
    let ref = 0;
    const pending = new Map();
    const client = {
      ws,
      onEvent: null,
      closing: false,
      push(topic, event, payload) {
        const r = String(++ref);
        ws.send(JSON.stringify([event === 'phx_join' ? r : '1', r, topic, event, payload]));
        return new Promise((res) => pending.set(r, res));
      },
      close() { client.closing = true; ws.close(1000); },
    };
    ws.on('message', (data) => {
      const [, r, , event, payload] = JSON.parse(data.toString());
      if (event === 'phx_reply' && pending.has(r)) { pending.get(r)(payload); pending.delete(r); }
      else if (client.onEvent) client.onEvent(event, payload);
    });
    if (onClosed) ws.on('close', (code) => { if (!client.closing) onClosed(code); });
    ws.once('open', () => resolve(client));
    ws.once('error', reject);
  });
}
