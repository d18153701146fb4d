// Entry of the browser viewer bundle that `simrun replay --html` inlines into its pages.
// scripts/install_three_viewer.sh bundles it with esbuild into tools/three-viewer/dist/viewer.js.
import * as THREE from "three";
import { GLTFLoader } from "three/addons/loaders/GLTFLoader.js";
import { OrbitControls } from "three/addons/controls/OrbitControls.js";

globalThis.SimrunThree = { THREE, GLTFLoader, OrbitControls };
