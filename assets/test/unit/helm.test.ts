import { describe, expect, it } from "vitest";
import { HELM_UNSEEN, heartbeatMsOf, helmRejoined, helmView, isPilot, seeGrant, seeHelm, seenView, stampOf } from "../../src/lib/helm";
import { ada, bob, free, grant, main, olga, piloted, requested, session, takeover } from "./helm_fixtures";

describe("helmView", () => {
  it("free: pilots and the main station may request, observers may not", () => {
    expect(helmView(free, session(ada))).toMatchObject({ me: "watching", canRequest: true, canTake: false, canRelease: false });
    expect(helmView(free, session(olga))).toMatchObject({ canRequest: false, canTake: false });
    expect(helmView(free, session(main))).toMatchObject({ canRequest: true, canTake: false });
    expect(helmView(free, session(ada)).summary).toBe("Free: nobody pilots");
  });

  it("piloted: the pilot may release; others request; the main station may also take", () => {
    expect(helmView(piloted(ada), session(ada))).toMatchObject({
      me: "pilot",
      summary: "You pilot",
      canRequest: false,
      canRelease: true,
      releaseLabel: "Release control",
    });
    expect(helmView(piloted(ada), session(bob))).toMatchObject({ me: "watching", summary: "ada pilots", canRequest: true });
    expect(helmView(piloted(ada), session(main))).toMatchObject({ canRequest: true, canTake: true });
    expect(helmView(piloted(ada), session(olga))).toMatchObject({ canRequest: false, canTake: false });
  });

  it("requested: the pilot gets a prompt with a countdown; others are busy", () => {
    const h = requested(ada, bob);
    const v = helmView(h, session(ada), 2500);
    expect(v.prompt).toEqual({ from: bob, remainingMs: 7500 });
    expect(v.summary).toBe("bob asks you for control (8 s)");
    expect(helmView(h, session(bob))).toMatchObject({ me: "requesting", canRelease: true, releaseLabel: "Withdraw request", prompt: null });
    expect(helmView(h, session({ ...bob, id: "c" }))).toMatchObject({ canRequest: false });
    expect(helmView(h, session(main))).toMatchObject({ canTake: true });
  });

  it("takeover: a warning for both parties with the countdown", () => {
    const h = takeover(ada, main);
    expect(helmView(h, session(ada), 1000).takeover).toEqual({ by: main, remainingMs: 2000, concernsMe: true });
    expect(helmView(h, session(main)).takeover?.concernsMe).toBe(true);
    expect(helmView(h, session(main))).toMatchObject({ me: "taking_over", releaseLabel: "Cancel takeover", canTake: false });
    expect(helmView(h, session(olga)).takeover?.concernsMe).toBe(false);
    expect(helmView(h, session(olga), 1000).summary).toBe("Main station main takes control from ada in 2 s");
  });

  it("no helm yet", () => {
    expect(helmView(null, null)).toMatchObject({ state: "unknown", canRequest: false });
  });
});

describe("HelmSeen", () => {
  it("stamps commands with the grant's epoch, only while piloting", () => {
    let t = helmRejoined(piloted(bob, 4), session(ada), 0);
    expect(stampOf(t)).toBeNull();
    const granted = seeGrant(t, grant(ada, 5));
    expect(granted).not.toBeNull();
    t = granted ?? t;
    // the same grant again (reply and event): not news
    expect(seeGrant(t, grant(ada, 5))).toBeNull();
    expect(isPilot(t)).toBe(true);
    expect(stampOf(t)).toBe(5);
    const same = seeHelm(t, piloted(ada, 5), 1);
    expect(same.change).toEqual({ becamePilot: false, lostPilot: false, restamped: false });
    const lost = seeHelm(same.seen, piloted(bob, 6), 2);
    expect(lost.change).toEqual({ becamePilot: false, lostPilot: true, restamped: false });
    expect(stampOf(lost.seen)).toBeNull();
  });

  it("reports a deadman restamp while we pilot", () => {
    const first = seeHelm(helmRejoined(free, session(ada), 0), piloted(ada, 1), 0);
    expect(first.change).toMatchObject({ becamePilot: true });
    expect(stampOf(first.seen)).toBe(1);
    const again = seeHelm(first.seen, piloted(ada, 2), 1);
    expect(again.change).toEqual({ becamePilot: false, lostPilot: false, restamped: true });
    expect(stampOf(again.seen)).toBe(2);
  });

  it("a grant for someone else keeps the helm, and nothing seen is no pilot", () => {
    expect(isPilot(HELM_UNSEEN)).toBe(false);
    const t = helmRejoined(piloted(bob, 4), session(ada), 0);
    expect(seeGrant(t, grant(bob, 5))).toEqual({ ...t, epoch: 5 });
  });

  it("counts down from when the helm arrived", () => {
    const { seen } = seeHelm(helmRejoined(null, session(ada), 0), takeover(ada, main), 1000);
    expect(seenView(seen, 2500).takeover?.remainingMs).toBe(1500);
    expect(heartbeatMsOf(seen)).toBe(100);
  });
});
