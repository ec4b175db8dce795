export interface FakeServer {
  /** e.g. "http://127.0.0.1:4199" */
  readonly url: string;
  /** Sends `event` with `payload` to every connection joined to `topic` (as the server would). */
  broadcast(topic: string, event: string, payload: unknown): void;
  close(): Promise<void>;
}

/** Starts the stand-in server on 127.0.0.1 (port 0: any free port). */
export function startFakeServer(port?: number): Promise<FakeServer>;
