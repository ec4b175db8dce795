import { useEffect, useState } from "preact/hooks";
import type { Store } from "./store";

/** The store's current state; re-renders the component on every change. */
export function useStore<S extends object>(store: Store<S>): S {
  const [state, setState] = useState<S>(store.get());
  useEffect(() => {
    setState(store.get());
    return store.subscribe(setState);
  }, [store]);
  return state;
}
