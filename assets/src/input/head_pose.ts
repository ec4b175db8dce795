/**
 * Head pose sources for the headset input: WebXR (an immersive VR session: the headset's
 * viewer pose) where the browser offers it, otherwise DeviceOrientation (a phone in a viewer;
 * on iOS it asks for permission first). Both report a quaternion in WebXR's frame
 * (see headset.ts). Feature-detected; no vendor-only API is needed.
 */

import { quatFromDeviceOrientation } from "./headset";
import type { Quaternion } from "./headset";

export type PoseSource = "webxr" | "orientation";

export interface HeadPose {
  readonly source: PoseSource;
  stop(): void;
}

// The part of WebXR we use (not in TypeScript's DOM library).
interface XRPoseLike {
  readonly transform: { readonly orientation: Quaternion };
}
interface XRFrameLike {
  getViewerPose(space: unknown): XRPoseLike | null | undefined;
}
interface XRSessionLike {
  requestReferenceSpace(type: string): Promise<unknown>;
  requestAnimationFrame(cb: (time: number, frame: XRFrameLike) => void): number;
  updateRenderState(state: { baseLayer?: unknown }): void;
  addEventListener(type: "end", cb: () => void): void;
  end(): Promise<void>;
}
interface XRSystemLike {
  isSessionSupported(mode: string): Promise<boolean>;
  requestSession(mode: string, options?: object): Promise<XRSessionLike>;
}
type XRWebGLLayerCtor = new (session: XRSessionLike, gl: WebGLRenderingContext) => unknown;

function xrSystem(): XRSystemLike | null {
  const nav = navigator as Navigator & { xr?: XRSystemLike };
  return nav.xr && typeof nav.xr.requestSession === "function" ? nav.xr : null;
}

async function startWebXR(onPose: (q: Quaternion) => void, onEnd: () => void): Promise<HeadPose | null> {
  const xr = xrSystem();
  const Layer = (window as Window & { XRWebGLLayer?: XRWebGLLayerCtor }).XRWebGLLayer;
  if (!xr || !Layer) return null;
  if (!(await xr.isSessionSupported("immersive-vr").catch(() => false))) return null;
  const session = await xr.requestSession("immersive-vr", { requiredFeatures: ["local"] });
  const canvas = document.createElement("canvas");
  const gl = canvas.getContext("webgl", { xrCompatible: true } as WebGLContextAttributes);
  if (!gl) {
    await session.end();
    return null;
  }
  session.updateRenderState({ baseLayer: new Layer(session, gl) });
  const space = await session.requestReferenceSpace("local");
  let running = true;
  session.addEventListener("end", () => {
    running = false;
    onEnd();
  });
  const frame = (_time: number, f: XRFrameLike): void => {
    if (!running) return;
    const pose = f.getViewerPose(space);
    if (pose) onPose(pose.transform.orientation);
    session.requestAnimationFrame(frame);
  };
  session.requestAnimationFrame(frame);
  return {
    source: "webxr",
    stop: () => {
      running = false;
      void session.end().catch(() => undefined);
    },
  };
}

type PermissionFn = () => Promise<"granted" | "denied" | "default">;

async function startOrientation(onPose: (q: Quaternion) => void): Promise<HeadPose | null> {
  if (typeof window.DeviceOrientationEvent === "undefined") return null;
  const ctor = window.DeviceOrientationEvent as unknown as { requestPermission?: PermissionFn };
  if (typeof ctor.requestPermission === "function") {
    const answer = await ctor.requestPermission();
    if (answer !== "granted") throw new Error("motion sensor permission was not granted");
  }
  const listener = (e: DeviceOrientationEvent): void => {
    if (e.alpha === null || e.beta === null || e.gamma === null) return;
    const angle = typeof screen.orientation?.angle === "number" ? screen.orientation.angle : 0;
    onPose(quatFromDeviceOrientation(e.alpha, e.beta, e.gamma, angle));
  };
  window.addEventListener("deviceorientation", listener);
  return { source: "orientation", stop: () => window.removeEventListener("deviceorientation", listener) };
}

/**
 * Starts the best pose source (call from a click: both APIs want a user gesture). Rejects with
 * a readable reason when this browser has neither.
 */
export async function startHeadPose(onPose: (q: Quaternion) => void, onEnd: () => void): Promise<HeadPose> {
  const xr = await startWebXR(onPose, onEnd).catch(() => null);
  if (xr) return xr;
  const orientation = await startOrientation(onPose);
  if (orientation) return orientation;
  throw new Error("this browser has no WebXR headset and no orientation sensor");
}
