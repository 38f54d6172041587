// What the router needs from a page: its element, live events, and cleanup.
import type { LiveEvent } from "../live";

export interface Page {
  el: HTMLElement;
  onEvent?(e: LiveEvent): void;
  dispose?(): void;
}

export function stateBadge(state: string): HTMLSpanElement {
  const s = document.createElement("span");
  s.className = `badge state-${state}`;
  s.textContent = state;
  return s;
}

export function progressBar(fraction: number, label: string): HTMLDivElement {
  const outer = document.createElement("div");
  outer.className = "progress";
  const bar = document.createElement("div");
  bar.className = "bar";
  bar.style.width = `${Math.round(Math.min(1, Math.max(0, fraction)) * 1000) / 10}%`;
  const text = document.createElement("span");
  text.className = "label";
  text.textContent = label;
  outer.append(bar, text);
  return outer;
}
