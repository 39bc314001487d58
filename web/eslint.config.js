// ESLint flat config for the viewer (web/src) and its unit tests (web/test): the recommended rules, browser
// globals for the viewer, Node's for the tests. `make lint` runs it (`npm ci --prefix web` installs eslint).
import js from '@eslint/js';
import globals from 'globals';

export default [
  {
    ignores: ['node_modules/**'],
  },
  js.configs.recommended,
  {
    files: ['src/**/*.js', 'packages/*/src/**/*.js'],
    languageOptions: {
      ecmaVersion: 2022,
      sourceType: 'module',
      globals: { ...globals.browser },
    },
  },
  {
    files: ['test/**/*.js', 'eslint.config.js', 'packages/*/test/**/*.js', 'packages/*/scripts/**/*.mjs'],
    languageOptions: {
      ecmaVersion: 2022,
      sourceType: 'module',
      globals: { ...globals.node },
    },
  },
];
