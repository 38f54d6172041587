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

// In-place updates: rows and headers that change several times a second keep their
// elements, so a click that lands between two updates is never lost.

export function setBadge(badge: HTMLElement, state: string): void {
  if (badge.textContent === state) return;
  badge.className = `badge state-${state}`;
  badge.textContent = state;
}

export function setProgress(progress: HTMLElement, fraction: number, label: string): void {
  const bar = progress.querySelector<HTMLElement>(".bar")!;
  bar.style.width = `${Math.round(Math.min(1, Math.max(0, fraction)) * 1000) / 10}%`;
  setText(progress.querySelector<HTMLElement>(".label")!, label);
}

export function setText(el: HTMLElement, text: string): void {
  if (el.textContent !== text) el.textContent = text;
}
