import { defineConfig } from "vitest/config";

// Unit tests only: test/protocol/ (node --test) and ../test/e2e/ need a running server.
export default defineConfig({
  test: {
    include: ["test/unit/**/*.test.ts"],
    environment: "node",
  },
});
