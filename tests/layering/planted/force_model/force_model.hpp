#pragma once
int predict();
