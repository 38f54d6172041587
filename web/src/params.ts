// A method's parameters as the coordinator declares them (GET /api/methods, from the one
// table in coordinator/strategies/strategy_parameters.h): what the submit form offers for
// the chosen method, what it sends, and what a render's page shows. No DOM here, so the
// rules are tested in node.
import type { MethodInfo, ParamInfo } from "./api";

export type ParamValue = number | string;

/** The method named, or undefined for one the coordinator does not list. */
export function findMethod(methods: MethodInfo[], name: string): MethodInfo | undefined {
  return methods.find((m) => m.name === name);
}

/** How a form field holds a parameter: an input's type, step and limits, or a select's options. */
export interface FieldSpec {
  key: string;
  label: string;
  /** The help and the bounds in words: the field's tooltip. */
  title: string;
  value: string;
  options?: string[];
  input?: { type: "number"; step: string; min?: string; max?: string };
}

/** The fields for one method's parameters, holding `values` where given and else the defaults. */
export function fieldSpecs(method: MethodInfo, values: Record<string, unknown> = {}): FieldSpec[] {
  return method.parameters.map((p) => {
    const given = values[p.key];
    const value = String(typeof given === "number" || typeof given === "string" ? given : p.default);
    const spec: FieldSpec = { key: p.key, label: p.key.replaceAll("_", " "), title: `${p.help} (${p.bounds})`, value };
    if (p.kind === "word") {
      spec.options = p.values ?? [];
    } else {
      spec.input = { type: "number", step: p.kind === "whole" ? "1" : "any" };
      // An open end cannot be said in HTML: the server's message names it.
      if (p.min !== undefined && !p.min_exclusive) spec.input.min = String(p.min);
      if (p.max !== undefined && !p.max_exclusive) spec.input.max = String(p.max);
    }
    return spec;
  });
}

function parsed(p: ParamInfo, text: string): ParamValue {
  return p.kind === "word" ? text : Number(text);
}

/**
 * The strategy to submit: the method and each of its parameters whose field differs from
 * the default (an empty field counts as the default), so the coordinator applies its own
 * defaults for the rest, and spp and budget are never both sent by accident.
 */
export function strategyFromFields(method: MethodInfo, fields: Record<string, string>): Record<string, ParamValue> {
  const out: Record<string, ParamValue> = { method: method.name };
  for (const p of method.parameters) {
    const text = (fields[p.key] ?? "").trim();
    if (text === "") continue;
    const value = parsed(p, text);
    if (value !== p.default) out[p.key] = value;
  }
  return out;
}

/** A render's parameters in words, only those its method reads: "spp 64 · max spp 1024". */
export function paramSummary(method: MethodInfo | undefined, strategy: Record<string, unknown> | undefined): string {
  if (!method || !strategy) return "";
  return method.parameters
    .filter((p) => strategy[p.key] !== undefined)
    .map((p) => `${p.key.replaceAll("_", " ")} ${String(strategy[p.key])}`)
    .join(" · ");
}
