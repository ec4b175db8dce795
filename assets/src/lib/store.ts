/**
 * A small observable state holder for a page: the page's controller `update`s it, the Preact
 * view subscribes (`useStore`). State is replaced, never mutated, so a view can compare.
 */

export type Listener<S> = (state: S) => void;

export class Store<S extends object> {
  private state: S;
  private readonly listeners = new Set<Listener<S>>();

  constructor(initial: S) {
    this.state = initial;
  }

  get(): S {
    return this.state;
  }

  /** Merges `patch` (or the result of `fn(state)`) into the state and notifies on change. */
  update(patch: Partial<S> | ((state: S) => Partial<S>)): void {
    const p = typeof patch === "function" ? patch(this.state) : patch;
    let changed = false;
    for (const key of Object.keys(p) as (keyof S)[]) {
      if (!Object.is(this.state[key], p[key])) {
        changed = true;
        break;
      }
    }
    if (!changed) return;
    this.state = { ...this.state, ...p };
    for (const listener of this.listeners) listener(this.state);
  }

  subscribe(listener: Listener<S>): () => void {
    this.listeners.add(listener);
    return () => this.listeners.delete(listener);
  }
}
